#pragma once
// Trajectories in EuRoC's csv (what evo's `euroc` readers take, and the first
// eight columns of a dataset's state_groundtruth_estimate0/data.csv): one pose
// per line "timestamp [ns],px,py,pz,qw,qx,qy,qz", '#' comments; and the choice
// between it and TUM for the commands that write trajectories.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"

namespace orbatlas {

enum class TrajectoryFormat { kTum, kEuroc };

// "tum" or "euroc"; throws Error naming the choices otherwise.
TrajectoryFormat parse_trajectory_format(const std::string& name);

// The csv text: a header comment, then per pose its integer nanoseconds and 9
// decimals of position and quaternion; with `maps` (index-aligned with the
// poses) a comment "# map <id>" before each run of poses of one map.
std::string format_euroc_trajectory(const Trajectory& trajectory, const std::vector<std::uint64_t>& maps = {});

// Throws DataError (file:line) on a line with fewer than 8 fields, a timestamp
// that is not an integer of nanoseconds or not after the previous one, a value
// that is not finite, or a quaternion off unit norm by more than 1e-3. Columns
// after the eighth (a ground-truth file's velocity and biases) are ignored.
Trajectory parse_euroc_trajectory(const std::string& text, const std::filesystem::path& source);
Trajectory read_euroc_trajectory(const std::filesystem::path& path);

// Writes `trajectory` to `path` in `format` (the TUM writer's map comments in both).
void write_trajectory(const std::filesystem::path& path, const Trajectory& trajectory,
                      const std::vector<std::uint64_t>& maps, TrajectoryFormat format);

}  // namespace orbatlas
