#include "wire/service_json.h"

#include <cstdio>
#include <sstream>

#include "wire/stats_json.h"

namespace orbatlas {

nlohmann::json to_json(const SessionStatus& s) {
  nlohmann::json j = {{"id", s.id},
                      {"name", s.name},
                      {"state", session_state_name(s.state)},
                      {"sensor", sensor_type_name(s.sensor)},
                      {"frames", s.frames},
                      {"tracked", s.tracked},
                      {"keyframes", s.keyframes},
                      {"rejected_frames", s.rejected_frames},
                      {"skipped_frames", s.skipped_frames},
                      {"maps_busy_frames", s.maps_busy_frames},
                      {"imu_samples", s.imu_samples},
                      {"worker_errors", s.worker_errors}};
  if (s.mode) j["mode"] = session_mode_name(*s.mode);
  if (!s.config.empty()) j["config"] = s.config;
  if (!s.error.empty()) j["error"] = s.error;
  if (!s.ended_by.empty()) j["ended_by"] = s.ended_by;
  if (!s.imu_warnings.empty()) j["imu_warnings"] = s.imu_warnings;
  if (s.map) j["map"] = *s.map;
  if (s.last_frame) j["last_frame"] = {{"t_ns", s.last_frame->t_ns}, {"tracked", s.last_frame->tracked}};
  if (!s.tracking_ms.empty()) j["tracking_ms"] = to_json_summary(s.tracking_ms);
  if (!s.live_jumps_m.empty()) j["live_jumps_m"] = to_json_summary(s.live_jumps_m);
  if (!s.request_ms.empty()) j["request_ms"] = to_json_summary(s.request_ms);
  if (!s.decode_ms.empty()) j["decode_ms"] = to_json_summary(s.decode_ms);
  if (!s.maps_wait_ms.empty()) j["maps_wait_ms"] = to_json_summary(s.maps_wait_ms);
  if (s.slam) {
    j["slam"] = {{"relocalizations", s.slam->relocalizations},
                 {"loops", s.slam->loops},
                 {"mapping_wait_ms", to_json_summary(s.slam->mapping_wait_ms)},
                 {"mapping_waits_cut", s.slam->mapping_waits_cut}};
    if (s.slam->imu_initialized_at_s) {
      const auto v = [](const Eigen::Vector3d& x) { return nlohmann::json::array({x.x(), x.y(), x.z()}); };
      j["slam"]["imu_initialized_at_s"] = *s.slam->imu_initialized_at_s;
      j["slam"]["imu_bias"] = {{"gyro", v(s.slam->imu_bias.gyro)}, {"acc", v(s.slam->imu_bias.accel)}};
    }
    if (s.slam->imu_time_offset_ms) j["slam"]["imu_time_offset_ms"] = *s.slam->imu_time_offset_ms;
    if (const auto& w = s.slam->imu_white_noise) j["slam"]["imu_white_noise"] = {{"gyro", w->gyro}, {"acc", w->accel}};
  }
  return j;
}

nlohmann::json to_json(const MapSummary& map) {
  nlohmann::json j = {{"id", map.id}, {"keyframes", map.keyframes}, {"map_points", map.map_points}};
  if (map.live_session) j["live_session"] = *map.live_session;
  j["sessions"] = map.sessions;
  j["writable"] = map.writable;
  if (map.bounds_m) {
    const auto& b = *map.bounds_m;
    j["bounds_m"] = {{"min", {b.min.x(), b.min.y(), b.min.z()}}, {"max", {b.max.x(), b.max.y(), b.max.z()}}};
  }
  return j;
}

nlohmann::json to_json(const MergesReport& m) {
  nlohmann::json out = {{"enabled", m.enabled}, {"pending", 0}, {"merges", nlohmann::json::array()}};
  if (!m.enabled) return out;
  out["live_merges"] = nlohmann::json::array();
  for (const LiveMergeRecord& r : m.live_merges) {
    nlohmann::json j = to_json(r.merge);
    j["session"] = r.session;
    out["live_merges"].push_back(std::move(j));
  }
  out["live_merges_total"] = m.live_merges_total;
  const MapMergeWorkerStats& stats = m.worker;
  out["pending"] = stats.pending;
  out["requests"] = stats.requests;
  out["skipped"] = stats.skipped;
  out["maps_searched"] = stats.maps_searched;
  out["keyframes_searched"] = stats.keyframes_searched;
  out["worker_errors"] = stats.errors;
  out["merges_total"] = stats.merges_total;
  out["refinements_total"] = stats.refinements_total;
  if (!stats.last_error.empty()) out["last_error"] = stats.last_error;
  out["refinements"] = nlohmann::json::array();
  for (const MapRefinement& r : stats.refinements)
    out["refinements"].push_back({{"map", r.map},
                                  {"keyframes", r.keyframes},
                                  {"inertial_edges", r.inertial_edges},
                                  {"seconds", r.seconds},
                                  {"interrupted", r.interrupted}});
  for (const MergeRecord& r : stats.merges) {
    nlohmann::json j = merge_json(r.merge);
    j["keyframe"] = r.current;
    j["matched_keyframe"] = r.matched;
    j["matches"] = r.matches;
    j["verified_keyframes"] = r.verified_keyframes;
    j["keyframes_searched"] = r.keyframes_searched;
    j["search_ms"] = r.search_ms;
    j["observations_added"] = r.merge.observations_fused;
    j["global_ba"] = {{"keyframes", r.ba_keyframes},
                      {"inertial_edges", r.ba_inertial_edges},
                      {"seconds", r.ba_seconds},
                      {"interrupted", r.ba_interrupted}};
    out["merges"].push_back(std::move(j));
  }
  return out;
}

nlohmann::json to_json(const HealthReport& h) {
  return {{"status", h.shutting_down ? "shutting_down" : "ok"},
          {"live_sessions", h.live_sessions},
          {"maps", h.maps},
          {"merges_pending", h.merges_pending}};
}

nlohmann::json replicas_json(const std::vector<ReplicaInfo>& replicas, const ReplicaRegistry& self) {
  nlohmann::json list = nlohmann::json::array();
  for (const ReplicaInfo& r : replicas) {
    list.push_back({{"id", r.id},
                    {"holder", r.holder},
                    {"url", r.url},
                    {"started_ns", r.started_ns},
                    {"state", r.state},
                    {"alive", r.alive},
                    {"lease_left_s", r.lease_left_s ? nlohmann::json(*r.lease_left_s) : nlohmann::json(nullptr)},
                    {"self", r.self}});
  }
  return {{"backend", self.shared() ? "postgresql" : "sqlite"},
          {"self", self.id()},
          {"lease_s", self.shared() ? nlohmann::json(self.options().lease_s) : nlohmann::json(nullptr)},
          {"lease_lost", self.lease_lost()},
          {"replicas", list}};
}

nlohmann::json to_json(const StoredJob& job) {
  nlohmann::json j = {{"id", job.id},
                      {"state", job.state},
                      {"name", job.name},
                      {"archive_bytes", job.archive_bytes},
                      {"frames_total", job.frames_total},
                      {"frames_done", job.frames_done},
                      {"tracked", job.tracked},
                      {"rejected", job.rejected},
                      {"progress", job.frames_total ? static_cast<double>(job.frames_done) / job.frames_total : 0.0}};
  if (job.session) j["session"] = *job.session;
  if (job.ate_rmse_m) j["ate_rmse_m"] = *job.ate_rmse_m;
  if (!job.error.empty()) j["error"] = job.error;
  return j;
}

std::string to_ply(const MapPointCloud& cloud) {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment orbatlas map " << cloud.map << " (world frame of the map, metres)\n"
      << "element vertex " << cloud.points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  char line[96];
  for (const auto& p : cloud.points) {
    std::snprintf(line, sizeof line, "%.5f %.5f %.5f\n", p.x(), p.y(), p.z());
    out << line;
  }
  return out.str();
}

}  // namespace orbatlas
