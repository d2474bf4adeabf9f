#include "core/slam/slam_stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace orbatlas {

Percentiles percentiles(std::vector<double> values) {
  Percentiles p;
  p.count = values.size();
  if (values.empty()) return p;
  std::sort(values.begin(), values.end());
  auto at = [&](double q) {
    const std::size_t i = static_cast<std::size_t>(std::lround(q * static_cast<double>(values.size() - 1)));
    return values[std::min(i, values.size() - 1)];
  };
  p.p50 = at(0.50);
  p.p95 = at(0.95);
  p.max = values.back();
  p.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
  return p;
}

namespace {

nlohmann::json summary(const std::vector<double>& values) {
  const Percentiles p = percentiles(values);
  return {{"p50", p.p50}, {"p95", p.p95}, {"max", p.max}, {"mean", p.mean}, {"count", p.count}};
}

nlohmann::json counters(const CounterSnapshot& c) {
  return {{"created", c.created}, {"culled", c.culled}, {"alive", c.alive()}, {"reclaimed", c.reclaimed}};
}

double mean(const std::vector<double>& v) {
  return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

}  // namespace

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
  j["tracking_ms"] = summary(s.tracking_ms);
  j["local_mapping_ms_per_kf"] = summary(s.mapping.keyframe_ms);
  j["local_ba_ms"] = summary(s.mapping.bundle_adjustment_ms);
  j["local_ba_interrupted"] = s.mapping.bundle_adjustments_interrupted;
  j["culling_scheme"] = culling_scheme_name(s.culling_scheme);
  const double scan = mean(s.mapping.culling_scan_ms), incremental = mean(s.mapping.culling_incremental_ms);
  j["culling_ms_per_kf"] = s.culling_scheme == CullingScheme::kScan ? scan : incremental;
  j["culling_ms_per_kf_by_scheme"] = {{"scan", s.mapping.culling_scan_ms.empty() ? nlohmann::json() : nlohmann::json(scan)},
                                      {"incremental", s.mapping.culling_incremental_ms.empty()
                                                          ? nlohmann::json()
                                                          : nlohmann::json(incremental)}};
  j["culling_candidates"] = s.mapping.culling_candidates;
  j["culling_disagreements"] = s.mapping.culling_disagreements;
  j["culled_keyframes"] = s.mapping.culled_keyframes.size();
  j["points_triangulated"] = s.mapping.points_triangulated;
  j["points_fused"] = s.mapping.points_fused;
  j["recent_points_culled"] = s.mapping.recent_points_culled;
  j["objects"] = {{"keyframes", counters(s.keyframe_objects)}, {"mappoints", counters(s.mappoint_objects)}};
  return j;
}

}  // namespace orbatlas
