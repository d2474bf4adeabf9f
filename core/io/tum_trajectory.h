#pragma once
// TUM trajectory files: one pose per line, "t tx ty tz qx qy qz qw", '#' comments.
// Timestamps are read exactly to the nanosecond. Reading also accepts ORB-SLAM3's
// output, whose first column is in nanoseconds ("1403636586363555584.000000"):
// a timestamp column whose values exceed 1e12 is taken as nanoseconds.
#include <cstdint>
#include <filesystem>
#include <string>

#include "core/geometry/trajectory.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

// Throws DataError (file:line) on malformed lines, non-unit quaternions (|q| off by
// more than 1e-3), or timestamps that are not strictly increasing.
Trajectory read_tum_trajectory(const std::filesystem::path& path);
// The same from text (`source` names it in errors). With `maps`, each pose's map
// id from the "# map <id>" line before its run (0 before any) is appended.
Trajectory parse_tum_trajectory(const std::string& text, const std::filesystem::path& source,
                                std::vector<std::uint64_t>* maps = nullptr);

// Writes seconds with 9 decimals (exact), positions and quaternions with 9 digits.
void write_tum_trajectory(const std::filesystem::path& path, const Trajectory& trajectory);
// The same, with a comment line "# map <id>" before each run of poses of one map
// (`maps` is index-aligned with the poses; readers skip comments).
void write_tum_trajectory(const std::filesystem::path& path, const Trajectory& trajectory,
                          const std::vector<std::uint64_t>& maps);

// Writes `text` to `path` (replaced); throws Error when it cannot. The
// trajectory writers' (TUM, EuRoC csv) last step.
void write_trajectory_text(const std::filesystem::path& path, const std::string& text);

// The text write_tum_trajectory writes (the server's trajectory route).
std::string format_tum_trajectory(const Trajectory& trajectory, const std::vector<std::uint64_t>& maps = {});

// Body poses of ground-truth states (a dataset's state_groundtruth_estimate0).
Trajectory from_ground_truth_states(const std::vector<GroundTruthState>& states);
// The other way: ground-truth states of poses alone (no velocity or biases).
std::vector<GroundTruthState> ground_truth_states(const Trajectory& poses);

// Reads ground truth in any of the forms `orbatlas eval --gt` takes: a TUM file,
// an ASL ground-truth csv, a EuRoC trajectory csv (euroc_trajectory.h), a KITTI
// poses file (kitti_odometry.h), or a dataset folder (an ASL recording's
// state_groundtruth_estimate0, a KITTI sequence's poses).
Trajectory read_any_ground_truth(const std::filesystem::path& path);

}  // namespace orbatlas
