#pragma once
// Runs a SLAM session over a recording (what `orbatlas run` does): an EuRoC
// ASL folder, a KITTI odometry sequence or a TUM RGB-D folder; images are
// decoded by a loader thread into a bounded queue, tracked, and optionally
// paced at the sensor rate.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/trajectory.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/slam/slam_system.h"

namespace orbatlas {

struct DatasetRunOptions {
  std::filesystem::path settings;    // ORB-SLAM3-style YAML; empty: a KITTI sequence's from its calib.txt
  std::filesystem::path dataset;     // the recording's folder
  std::filesystem::path vocabulary;  // empty: the shipped one
  SlamSystemOptions slam;
  double start_s = 0.0;              // skip this much of the sequence
  std::optional<double> duration_s;  // and stop after this much
  bool realtime = false;             // feed frames at their timestamps; count the late ones
  // Persistent atlas (docs/schema.md): the stored maps are loaded first (and
  // indexed for relocalisation); a SLAM run is stored as a new session with its
  // maps, by incremental checkpoints off the tracking thread and a final one.
  std::filesystem::path atlas;
  CheckpointOptions checkpoints;
  // Localisation on the stored maps (needs `atlas`): no keyframe, no new map,
  // nothing written; the trajectory holds the localised frames only.
  bool localize_only = false;
  bool show_progress = true;
  // Every image black from `first` to `second` seconds after the run's first
  // frame (`orbatlas run --black-out`: what the IMU carries a session through).
  std::optional<std::pair<double, double>> black_out_s;
  // A single camera of a stereo config (kMonocular, kMonocularInertial): its
  // left camera alone, rectified as the rig's stereo maps are (`--sensor`).
  std::optional<SensorType> sensor;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct DatasetRunReport {
  Trajectory trajectory;               // every tracked frame, body frame
  std::vector<MapId> trajectory_maps;  // map of each trajectory pose
  SlamStats stats;
  std::size_t skipped_frames = 0;  // unreadable images, reported and skipped
  std::size_t late_frames = 0;     // realtime: processing ended after the next frame arrived
  double peak_rss_mb = 0.0;
  double wall_s = 0.0;
  // The pose track() returned for each frame it tracked, as it was returned
  // (what a device would have steered by; `trajectory` is the final, corrected
  // one), with its map and the jumps at corrections of the maps (live_pose_jumps.h).
  Trajectory live_trajectory;
  std::vector<MapId> live_maps;
  std::vector<double> live_jumps_m;
  std::optional<double> live_ate_rmse_m;  // the live poses, scored as the final ones
  std::optional<double> ate_rmse_m;       // when the dataset has ground truth (SE3 alignment)
  bool ate_sim3 = false;                  // monocular: the camera's poses, Sim(3) alignment
  // With an atlas: what was loaded, the session stored, and the checkpoints.
  std::size_t loaded_maps = 0, loaded_keyframes = 0;
  double atlas_load_s = 0.0;
  std::optional<SessionId> session;
  std::optional<CheckpointStats> checkpoints;
  // Set when the run stopped early because the session failed (a worker gave up
  // on the map, WorkerFailed): the frames tracked until then are still reported,
  // stored and written.
  std::string failed;
  // With black_out_s: the frames blacked out, those the IMU carried, the frames
  // after the gap until one was tracked visually again (0: the first; none:
  // never), and with ground truth the error at the gap's end (gap_error.h).
  struct BlackOut {
    std::size_t frames = 0, by_imu = 0;
    std::optional<std::size_t> frames_to_visual;
    std::optional<double> error_at_end_m, error_after_m;
  };
  std::optional<BlackOut> black_out;
};

// Throws Error for unusable settings, a missing dataset or a non-stereo dataset;
// a session that fails while it runs ends the run with `failed` set instead.
DatasetRunReport run_dataset(const DatasetRunOptions& options);

// Several recordings at once into one atlas (`orbatlas run --dataset A
// --dataset B`): one session each (options.dataset is ignored), each on its own
// thread, all attached to one mapping (MappingWorkers: recordings that see the
// same place map in one map together). One report per recording, in order; the
// mapping and loop-closing figures in each are those of the shared mapping.
// --final-ba is not run (it is a single session's refinement). One recording:
// exactly run_dataset().
std::vector<DatasetRunReport> run_datasets(const DatasetRunOptions& options,
                                           const std::vector<std::filesystem::path>& datasets);

}  // namespace orbatlas
