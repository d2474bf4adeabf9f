#include "wire/stats_json.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace orbatlas {

namespace {

nlohmann::json summary(const Percentiles& p) {
  return {{"p50", p.p50}, {"p95", p.p95}, {"p99", p.p99}, {"max", p.max}, {"mean", p.mean}, {"count", p.count}};
}
nlohmann::json summary(const std::vector<double>& values) { return summary(percentiles(values)); }
nlohmann::json summary(const SampleSummary& values) { return summary(values.percentiles()); }

nlohmann::json counters(const CounterSnapshot& c) {
  return {{"created", c.created}, {"culled", c.culled}, {"alive", c.alive()}, {"reclaimed", c.reclaimed}};
}

double mean(const SampleSummary& v) { return v.mean(); }

}  // namespace

nlohmann::json to_json_summary(const std::vector<double>& values) { return summary(values); }
nlohmann::json to_json_summary(const SampleSummary& values) { return summary(values); }

nlohmann::json merge_json(const MapMergeStats& merge) {
  return {{"source_map", merge.source},
          {"target_map", merge.target},
          {"keyframes_moved", merge.keyframes_moved},
          {"map_points_moved", merge.points_moved},
          {"points_fused", merge.points_fused},
          {"four_dof", merge.four_dof},
          {"scale", merge.scale},
          {"merge_ms", merge.ms}};
}

nlohmann::json to_json(const LiveMerge& m) {
  nlohmann::json j = merge_json(m.merge);
  j["keyframe"] = m.current;
  j["matched_keyframe"] = m.matched;
  j["keyframe_t_s"] = static_cast<double>(m.current_t_ns) * 1e-9;
  j["matches"] = m.matches;
  j["verified_keyframes"] = m.verified_keyframes;
  return j;
}

nlohmann::json to_json(const SlamStats& s) {
  nlohmann::json j;
  j["frames"] = s.frames;
  j["tracked"] = s.tracked;
  j["lost"] = s.lost;
  j["maps"] = s.maps;
  j["keyframes"] = s.keyframes;
  j["mappoints"] = s.mappoints;
  j["keyframes_made"] = s.keyframes_made;
  j["relocalizations"] = s.relocalizations;
  j["maps_started"] = s.maps_started;
  if (s.inertial) {
    // Full visual-inertial BAs: local mapping's own, and those it asked of the
    // loop closer (global adjustments of cause "inertial", in the background).
    std::size_t full_bas = s.mapping.full_inertial_bundle_adjustments;
    for (const GlobalAdjustmentRun& g : s.loop.global_adjustments)
      if (g.cause == GlobalAdjustmentCause::kInertial && !g.interrupted) ++full_bas;
    j["imu"] = {{"samples", s.imu_samples},
                {"linked_keyframes", s.imu_linked_keyframes},
                {"uncovered_keyframes", s.imu_uncovered_keyframes},
                {"frames_optimized", s.frames_optimized_with_imu},
                {"local_bas", s.mapping.inertial_bundle_adjustments},
                {"local_ba_chi2_median", summary(s.mapping.inertial_chi2_median)},
                {"refinements", s.mapping.inertial_refinements},
                {"resets", s.mapping.inertial_resets},
                {"given_up", s.mapping.inertial_given_up},
                {"full_bas", full_bas},
                {"full_ba_ms", summary(s.mapping.full_inertial_ba_ms)}};
    j["frames_tracked_by_imu"] = s.frames_tracked_by_imu;
    if (s.imu_time_offset_ms) j["imu_time_offset_ms"] = *s.imu_time_offset_ms;
    if (const auto& w = s.imu_white_noise) j["imu_white_noise"] = {{"gyro", w->gyro}, {"acc", w->accel}};
    const ImuInputHealth& h = s.imu_input;
    j["imu_input"] = {{"dropped_non_finite", h.non_finite},
                      {"dropped_stuck", h.stuck},
                      {"dropped_saturated", h.saturated},
                      {"gaps", h.gaps},
                      {"longest_gap_ms", h.longest_gap_s * 1e3},
                      {"frames_outside", h.frames_outside},
                      {"warnings", h.warnings}};
    if (h.rate_hz) j["imu_input"]["rate_hz"] = *h.rate_hz;
    if (s.imu_initialized_at_s) {
      const auto v = [](const Eigen::Vector3d& x) { return nlohmann::json::array({x.x(), x.y(), x.z()}); };
      j["imu_initialized_at_s"] = *s.imu_initialized_at_s;
      j["imu_gravity_w"] = v(s.imu_gravity_w);
      j["imu_bias"] = {{"gyro", v(s.imu_bias.gyro)}, {"acc", v(s.imu_bias.accel)}};
      j["imu_scale_correction"] = {{"gyro", v(s.imu_scale.gyro)}, {"acc", v(s.imu_scale.accel)}};
    }
  }
  j["live_merges"] = s.loop.merges.size();
  j["tracking_ms"] = summary(s.tracking_ms);
  j["local_map_keyframes"] = summary(s.local_map_keyframes);
  j["local_map_points"] = summary(s.local_map_points);
  j["maps_wait_ms"] = summary(s.maps_wait_ms);
  j["maps_busy_frames"] = s.maps_busy_frames;
  j["mapping_wait_ms"] = summary(s.mapping_wait_ms);
  j["mapping_waits_cut"] = s.mapping_waits_cut;
  j["local_mapping_ms_per_kf"] = summary(s.mapping.keyframe_ms);
  j["local_ba_ms"] = summary(s.mapping.bundle_adjustment_ms);
  j["local_ba_interrupted"] = s.mapping.bundle_adjustments_interrupted;
  j["local_ba_window_keyframes"] = summary(s.mapping.bundle_adjustment_window);
  j["local_ba_fixed_keyframes"] = summary(s.mapping.bundle_adjustment_fixed);
  j["culling_scheme"] = culling_scheme_name(s.culling_scheme);
  const double scan = mean(s.mapping.culling_scan_ms), incremental = mean(s.mapping.culling_incremental_ms);
  j["culling_ms_per_kf"] = s.culling_scheme == CullingScheme::kScan ? scan : incremental;
  j["culling_ms_per_kf_by_scheme"] = {
      {"scan", s.mapping.culling_scan_ms.empty() ? nlohmann::json() : nlohmann::json(scan)},
      {"incremental", s.mapping.culling_incremental_ms.empty() ? nlohmann::json() : nlohmann::json(incremental)}};
  j["culling_candidates"] = s.mapping.culling_candidates;
  j["culling_disagreements"] = s.mapping.culling_disagreements;
  j["culled_keyframes"] = s.mapping.culled_keyframes;
  j["points_triangulated"] = s.mapping.points_triangulated;
  j["points_fused"] = s.mapping.points_fused;
  j["recent_points_culled"] = s.mapping.recent_points_culled;
  j["loops"] = s.loop.loops.size();
  if (s.final_ba_keyframes > 0)
    j["final_global_ba"] = {
        {"keyframes", s.final_ba_keyframes}, {"inertial_edges", s.final_ba_inertial_edges}, {"seconds", s.final_ba_s}};
  if (s.loop_closing) {
    nlohmann::json lc;
    lc["keyframes"] = s.loop.keyframes;
    lc["keyframes_skipped"] = s.loop.keyframes_skipped;
    lc["hypotheses"] = s.loop.hypotheses;
    lc["place_recognition_ms_per_kf"] = summary(s.loop.place_recognition_ms);
    std::vector<double> correction_ms;
    nlohmann::json loops = nlohmann::json::array();
    for (std::size_t i = 0; i < s.loop.loops.size(); ++i) {
      const ClosedLoop& l = s.loop.loops[i];
      correction_ms.push_back(l.correction.total_ms);
      nlohmann::json e = {{"current_keyframe", l.current},
                          {"matched_keyframe", l.matched},
                          {"current_t_s", static_cast<double>(l.current_t_ns) * 1e-9},
                          {"matched_t_s", static_cast<double>(l.matched_t_ns) * 1e-9},
                          {"matches", l.matches},
                          {"correction_m", l.correction.correction_m},
                          {"correction_deg", l.correction.correction_deg},
                          {"group_keyframes", l.correction.group_keyframes},
                          {"points_fused", l.correction.points_fused},
                          {"essential_graph_edges", l.correction.graph_edges},
                          {"essential_graph_ms", l.correction.graph_ms},
                          {"correction_ms", l.correction.total_ms}};
      if (i < s.loop_error_m.size()) {
        e["error_m"] = s.loop_error_m[i];
        e["error_deg"] = s.loop_error_deg[i];
      }
      loops.push_back(e);
    }
    lc["loop_correction_ms"] = summary(correction_ms);
    lc["loops"] = loops;
    nlohmann::json gba = nlohmann::json::array();
    for (const auto& g : s.loop.global_adjustments)
      gba.push_back({{"cause", to_string(g.cause)},
                     {"keyframes", g.keyframes},
                     {"points", g.points},
                     {"inertial_edges", g.inertial_edges},
                     {"seconds", g.seconds},
                     {"interrupted", g.interrupted}});
    lc["global_ba"] = gba;
    nlohmann::json merges = nlohmann::json::array();
    for (const auto& m : s.loop.merges) merges.push_back(to_json(m));
    lc["live_merges"] = merges;
    if (!s.loop.merge_search_ms.empty()) lc["merge_search_ms_per_kf"] = summary(s.loop.merge_search_ms);
    if (!s.loop_error_m.empty()) {
      std::size_t false_loops = 0;
      for (std::size_t i = 0; i < s.loop_error_m.size(); ++i)
        if (s.loop_error_m[i] > kFalseLoopM || s.loop_error_deg[i] > kFalseLoopDeg) ++false_loops;
      lc["false_loops"] = false_loops;
    }
    j["loop_closing"] = lc;
  }
  j["objects"] = {{"keyframes", counters(s.keyframe_objects)}, {"mappoints", counters(s.mappoint_objects)}};
  j["worker_errors"] = worker_error_total(s);
  j["worker_errors_by"] = {{"tracking", s.tracking_errors.errors},
                           {"local_mapping", s.mapping.errors.errors},
                           {"loop_closing", s.loop.errors.errors}};
  for (const WorkerErrorCounts* e : {&s.loop.errors, &s.mapping.errors, &s.tracking_errors})
    if (!e->last.empty()) j["last_worker_error"] = e->last;
  j["slot_races"] = s.slot_races;
  if (s.monocular) j["monocular"] = {{"attempts", s.monocular_attempts}, {"starts", s.monocular_starts}};
  return j;
}

}  // namespace orbatlas
