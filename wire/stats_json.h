#pragma once
// The JSON form of a SLAM run's figures (the `orbatlas run --stats` file, the
// session's `slam` in the API) and of the samples every report summarises.
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/sample_summary.h"
#include "core/slam/slam_stats.h"

namespace orbatlas {

// {p50, p95, max, mean, count} of the values.
nlohmann::json to_json_summary(const std::vector<double>& values);
nlohmann::json to_json_summary(const SampleSummary& summary);

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
// imu_time_offset_ms (once estimated), imu_white_noise{gyro, acc} (the densities of the last
// keyframe link), frames_tracked_by_imu, imu_initialized_at_s, imu_gravity_w, imu_bias{gyro,
// acc}, imu_scale_correction{gyro, acc} (once initialised).
nlohmann::json to_json(const SlamStats& stats);
// One live merge (the stats' loop_closing.live_merges[], the server's GET /v1/merges
// live_merges[]): merge_json's keys, keyframe, matched_keyframe, keyframe_t_s,
// matches, verified_keyframes.
nlohmann::json to_json(const LiveMerge& merge);
// What a map merge did, the keys every merge record shares: source_map,
// target_map, keyframes_moved, map_points_moved, points_fused, four_dof, scale, merge_ms.
nlohmann::json merge_json(const MapMergeStats& merge);

}  // namespace orbatlas
