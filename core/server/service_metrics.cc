#include "core/server/service_metrics.h"

#include <string>
#include <utility>

#include "core/common/process_memory.h"

namespace orbatlas {

ServiceMetrics::ServiceMetrics()
    : sessions_created_(
          registry_.counter("orbatlas_sessions_created_total", "Sessions created since the server started.")),
      sessions_timed_out_(registry_.counter("orbatlas_sessions_timed_out_total",
                                            "Live sessions the server finished after their idle timeout.")),
      frames_(registry_.counter("orbatlas_frames_total", "Frames processed.")),
      frames_rejected_(registry_.counter("orbatlas_frames_rejected_total", "Frames refused as bad input.")),
      frames_skipped_(registry_.counter("orbatlas_frames_skipped_total",
                                        "Frames of real-time sessions skipped for arriving too late (max_lag_s).")),
      frames_maps_busy_(registry_.counter(
          "orbatlas_frames_maps_busy_total",
          "Frames of real-time sessions answered untracked: the maps were held by an edit past --max-maps-wait-ms.")),
      tracking_latency_(registry_.histogram("orbatlas_tracking_latency_seconds",
                                            "Time to track one frame (features included).", latency_buckets_seconds())),
      frame_request_latency_(registry_.histogram(
          "orbatlas_frame_request_seconds",
          "A live frame's time in the server, from its request's handling to its reply (decoding and tracking).",
          latency_buckets_seconds())),
      live_pose_jumps_(
          registry_.histogram("orbatlas_live_pose_jump_meters",
                              "How far a live session's pose jumped at the first frame after a correction of the maps.",
                              {0.001, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0})),
      localize_requests_(registry_.counter("orbatlas_localize_requests_total", "Localisation requests.")),
      localize_recognised_(
          registry_.counter("orbatlas_localize_recognised_total", "Localisation requests that recognised the place.")),
      localize_latency_(registry_.histogram("orbatlas_localize_latency_seconds",
                                            "Time to answer a localisation request.", latency_buckets_seconds())) {}

void ServiceMetrics::frame_done(double tracking_ms, double request_ms) {
  frames_.Increment();
  tracking_latency_.Observe(tracking_ms / 1000.0);
  frame_request_latency_.Observe(request_ms / 1000.0);
}

void ServiceMetrics::localized(bool recognised, double ms) {
  localize_requests_.Increment();
  if (recognised) localize_recognised_.Increment();
  localize_latency_.Observe(ms / 1000.0);
}

std::vector<prometheus::MetricFamily> ServiceMetrics::collect(const ServiceState& now) {
  // Per map: what it holds and how many live sessions track in it now (built
  // at each scrape: a merged map's series goes with it).
  prometheus::MetricFamily map_sessions{"orbatlas_map_sessions",
                                        "Live sessions whose last frame was tracked in the map.",
                                        prometheus::MetricType::Gauge,
                                        {}};
  prometheus::MetricFamily map_keyframes{
      "orbatlas_map_keyframes", "Keyframes in the map.", prometheus::MetricType::Gauge, {}};
  for (const ServiceState::MapState& m : now.maps) {
    const prometheus::ClientMetric::Label label{"map", std::to_string(m.map)};
    prometheus::ClientMetric sessions, kfs;
    sessions.label = {label};
    sessions.gauge.value = static_cast<double>(m.sessions);
    kfs.label = {label};
    kfs.gauge.value = static_cast<double>(m.keyframes);
    map_sessions.metric.push_back(std::move(sessions));
    map_keyframes.metric.push_back(std::move(kfs));
  }
  // What is a state, not an event, is set now; totals other parts keep
  // (checkpoints, merges, worker errors) advance their counters to the total.
  std::lock_guard scrape(scrape_mutex_);
  const auto set = [&](const char* name, const char* help, double value) { registry_.gauge(name, help).Set(value); };
  const auto total = [&](const char* name, const char* help, double value) {
    advance_counter_to(registry_.counter(name, help), value);
  };
  set("orbatlas_sessions_live", "Sessions taking frames.", static_cast<double>(now.live_sessions));
  set("orbatlas_sessions_ended", "Sessions finished, failed or stored by earlier runs.",
      static_cast<double>(now.ended_sessions));
  total("orbatlas_worker_errors_total",
        "Errors contained inside tracking, local mapping, loop closing and map merging (the unit of work was given up, "
        "the session and the server went on), over the sessions this server holds.",
        static_cast<double>(now.worker_errors));
  set("orbatlas_maps", "Maps in the atlas.", static_cast<double>(now.maps.size()));
  set("orbatlas_keyframes", "Keyframes in the atlas.", static_cast<double>(now.keyframes));
  set("orbatlas_map_points", "Map points in the atlas.", static_cast<double>(now.map_points));
  set("orbatlas_resident_bytes", "Resident memory of the server process (VmRSS).", current_rss_mb() * 1024.0 * 1024.0);
  set("orbatlas_heap_in_use_bytes", "C heap the server holds now (the allocator keeps the rest of the resident heap).",
      heap_in_use_mb() * 1024.0 * 1024.0);
  set("orbatlas_database_bytes", "Size of the atlas database with its write-ahead log.",
      static_cast<double>(now.database_bytes));
  set("orbatlas_local_mappers", "Maps whose local mapping runs now (one thread each).",
      static_cast<double>(now.mappers));
  total("orbatlas_mapped_keyframes_total", "Keyframes local mapping has processed.",
        static_cast<double>(now.mapped_keyframes));
  total("orbatlas_loops_closed_total", "Loops closed in live sessions' maps.", static_cast<double>(now.loops));
  total("orbatlas_global_adjustments_total",
        "Global bundle adjustments of live sessions' maps: after loops and live merges, of maps several sessions "
        "map (interrupted ones included).",
        static_cast<double>(now.global_adjustments));
  total("orbatlas_stream_end_adjustments_total",
        "Of those, the ones run when a session ended in a map other sessions mapped too (--finish-refinement-wait).",
        static_cast<double>(now.stream_end_adjustments));
  total("orbatlas_checkpoints_total", "Checkpoints completed.", static_cast<double>(now.checkpoints.checkpoints));
  total("orbatlas_checkpoint_failures_total", "Checkpoints that failed (retried).",
        static_cast<double>(now.checkpoints.failures));
  total("orbatlas_checkpoint_rows_total",
        "Database rows the checkpoints inserted, updated or deleted (maps, keyframes, points, observations, "
        "trajectories, sessions).",
        static_cast<double>(now.checkpoints.total_rows.total()));
  set("orbatlas_replica_id",
      "This server's id among the replicas of the atlas's database (GET /v1/replicas; 1 for an SQLite atlas).",
      static_cast<double>(now.replica_id));
  total("orbatlas_replica_lease_renewals_total", "Renewals of this replica's lease in a PostgreSQL atlas.",
        static_cast<double>(now.lease_renewals));
  total("orbatlas_replica_lease_renewal_failures_total",
        "Renewals of this replica's lease that failed (the database unreachable; retried).",
        static_cast<double>(now.lease_renewal_failures));
  set("orbatlas_replica_lease_lost",
      "1 when this replica's lease passed before it was renewed (others may hold what it held).",
      now.lease_lost ? 1.0 : 0.0);
  if (now.merging) {
    total("orbatlas_map_merges_total",
          "Maps merged into another map since the server started (live and at a session's end).",
          static_cast<double>(now.merging->merges_total));
    set("orbatlas_map_merge_pending", "Maps waiting for (or in) the merging worker.",
        static_cast<double>(now.merging->pending));
  }
  std::vector<prometheus::MetricFamily> out = registry_.collect();
  out.push_back(std::move(map_sessions));
  out.push_back(std::move(map_keyframes));
  return out;
}

}  // namespace orbatlas
