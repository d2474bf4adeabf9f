#pragma once
// Figures of a SLAM run (their JSON form, the `orbatlas run --stats` file: wire/stats_json.h).
#include <cstddef>
#include <string>
#include <optional>
#include <vector>

#include "core/common/sample_summary.h"
#include "core/map/atlas.h"
#include "core/map/object_counters.h"
#include "core/imu/imu_input_check.h"
#include "core/imu/imu_noise.h"
#include "core/imu/white_noise_estimate.h"
#include "core/loop/loop_closer.h"
#include "core/mapping/local_mapper.h"

namespace orbatlas {

struct SlamStats {
  std::size_t frames = 0, tracked = 0, lost = 0;       // lost: frames without a pose
  std::size_t maps = 0, keyframes = 0, mappoints = 0;  // in the atlas at the end
  std::size_t keyframes_made = 0;
  std::size_t relocalizations = 0;
  std::size_t maps_started = 0;  // by tracking (the first one included)
  SampleSummary tracking_ms;     // per frame: front end + tracking
  // Per frame tracked in a local map: its keyframes, and the map points of
  // theirs projected into the frame (what the local-map search costs).
  SampleSummary local_map_keyframes, local_map_points;
  // Per frame: the wait for the atlas's maps (an edit of loop closing,
  // merging or a global BA holds them), in tracking_ms.
  SampleSummary maps_wait_ms;
  std::size_t maps_busy_frames = 0;  // not tracked: the maps were held past max_maps_wait_ms
  // Before the frame after each keyframe: the wait for local mapping to adjust
  // it (TrackerOptions::max_mapping_wait_ms), and the waits cut at that bound.
  SampleSummary mapping_wait_ms;
  std::size_t mapping_waits_cut = 0;
  LocalMapperStats mapping;
  bool loop_closing = false;  // the loop closer ran
  LoopClosingStats loop;
  // Per closed loop, when ground truth is known (dataset runs): the error of the
  // estimated relative pose between the two keyframes; a false loop is off by
  // more than kFalseLoopM or kFalseLoopDeg.
  std::vector<double> loop_error_m, loop_error_deg;
  CullingScheme culling_scheme = CullingScheme::kIncremental;
  CounterSnapshot keyframe_objects, mappoint_objects;
  // The final global BA (SlamSystemOptions::final_global_ba), when it ran.
  std::size_t final_ba_keyframes = 0;
  std::size_t final_ba_inertial_edges = 0;  // IMU terms (inertial maps)
  double final_ba_s = 0.0;
  // Errors contained inside the engine (frames / keyframes given up, the
  // session went on); mapping.errors and loop.errors hold the other workers'.
  WorkerErrorCounts tracking_errors;
  // New-keyframe slots local mapping filled while tracking filled them (handled).
  std::size_t slot_races = 0;
  // Single-camera sessions that map: two-view reconstructions tried, and maps
  // started from one (the rest waited for more parallax).
  bool monocular = false;
  std::size_t monocular_attempts = 0, monocular_starts = 0;
  // Visual-inertial sessions: IMU samples received, keyframes linked
  // to their predecessor by preintegrated IMU, and the inertial initialisation
  // of the map the session is in (when it happened: seconds since the session's
  // first frame; the gravity in the map's frame; the biases it found).
  bool inertial = false;
  // Frames tracked by the IMU alone (their pose predicted while the images
  // could not be tracked; not in `tracked`, not in `lost`), and frames whose
  // pose was optimised with the IMU.
  std::size_t frames_tracked_by_imu = 0, frames_optimized_with_imu = 0;
  std::size_t imu_samples = 0, imu_linked_keyframes = 0, imu_uncovered_keyframes = 0;
  std::optional<double> imu_initialized_at_s;
  // The camera-IMU clock offset estimated (an image's IMU time is its stamp
  // plus this), once the session has one.
  std::optional<double> imu_time_offset_ms;
  // The white-noise densities of the last keyframe link's increments: the
  // settings', or those measured in the samples where above them
  // (core/imu/white_noise_estimate.h). Once a keyframe was linked.
  std::optional<WhiteNoiseDensities> imu_white_noise;
  // What the IMU stream carried that could not be used (dropped samples,
  // gaps, its rate; core/imu/imu_input_check.h), and the warnings given.
  ImuInputHealth imu_input;
  Eigen::Vector3d imu_gravity_w = Eigen::Vector3d::Zero();
  ImuBias imu_bias;
  ImuScaleCorrection imu_scale;  // the map's estimate of the IMU's scale factors' correction
};

// Every worker's contained errors together (tracking, local mapping, loop closing).
std::size_t worker_error_total(const SlamStats& stats);

// Fills maps, keyframes, mappoints (maps holding keyframes) and the object counters from the
// atlas as it is now.
void add_atlas_counts(const Atlas& atlas, SlamStats& stats);

// A loop whose correction moved the keyframe more than this is counted as false (stats).
inline constexpr double kFalseLoopM = 0.2, kFalseLoopDeg = 5.0;

}  // namespace orbatlas
