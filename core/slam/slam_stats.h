#pragma once
// Figures of a SLAM run, and their JSON form (the `orbatlas run --stats` file).
#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>
#include <optional>
#include <vector>

#include "core/common/sample_summary.h"
#include "core/map/atlas.h"
#include "core/map/object_counters.h"
#include "core/imu/imu_input_check.h"
#include "core/imu/imu_noise.h"
#include "core/loop/loop_closer.h"
#include "core/mapping/local_mapper.h"

namespace orbatlas {

// {p50, p95, max, mean, count} of the values.
nlohmann::json to_json_summary(const std::vector<double>& values);
nlohmann::json to_json_summary(const SampleSummary& summary);

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
  // The final global BA (StereoSlamOptions::final_global_ba), when it ran.
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
  // What the IMU stream carried that could not be used (dropped samples,
  // gaps, its rate; core/imu/imu_input_check.h), and the warnings given.
  ImuInputHealth imu_input;
  Eigen::Vector3d imu_gravity_w = Eigen::Vector3d::Zero();
  ImuBias imu_bias;
};

// Every worker's contained errors together (tracking, local mapping, loop closing).
std::size_t worker_error_total(const SlamStats& stats);

// Keys: frames, tracked, lost, maps, keyframes, mappoints, tracking_ms{p50,p95,max,mean},
// local_map_keyframes{p50,p95,max,mean,count}, local_map_points{...}, maps_wait_ms{...},
// mapping_wait_ms{p50,p95,max,mean,count}, mapping_waits_cut,
// local_mapping_ms_per_kf{p50,p95,max}, local_ba_ms{p50,p95,max}, culling_scheme,
// culling_ms_per_kf (the scheme in use), culling_ms_per_kf_by_scheme{scan,incremental},
// culling_disagreements, culled_keyframes, points_triangulated, points_fused,
// objects{keyframes,mappoints}{created,culled,alive,reclaimed}, loops,
// loop_closing{place_recognition_ms_per_kf, loop_correction_ms, loops[],
// global_ba[], false_loops, live_merges[], merge_search_ms_per_kf}, maps_started,
// live_merges (count), final_global_ba{keyframes, seconds} (when it ran),
// worker_errors (total), worker_errors_by{tracking, local_mapping, loop_closing},
// last_worker_error (when any), slot_races; monocular{attempts, starts} (a single
// camera that maps); with an IMU: imu{samples, linked_keyframes,
// uncovered_keyframes, frames_optimized}, imu_input{dropped_non_finite, dropped_stuck,
// dropped_saturated, gaps, longest_gap_ms, frames_outside, rate_hz, warnings},
// imu_time_offset_ms (once estimated), frames_tracked_by_imu, imu_initialized_at_s, imu_gravity_w, imu_bias{gyro,
// acc} (once initialised). Fills maps, keyframes, mappoints (maps holding keyframes) and the object counters from the
// atlas as it is now.
void add_atlas_counts(const Atlas& atlas, SlamStats& stats);

inline constexpr double kFalseLoopM = 0.2, kFalseLoopDeg = 5.0;
nlohmann::json to_json(const SlamStats& stats);
// One live merge (the stats' loop_closing.live_merges[], the server's GET /v1/merges
// live_merges[]): source_map, target_map, keyframe, matched_keyframe, keyframe_t_s,
// matches, verified_keyframes, keyframes_moved, map_points_moved, points_fused, merge_ms.
nlohmann::json to_json(const LiveMerge& merge);

}  // namespace orbatlas
