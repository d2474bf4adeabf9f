// AtlasService: what the server reports about itself: GET /healthz and the
// figures of GET /metrics (counters counted as things happen; states read now;
// per-map families built at each scrape).
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "core/common/process_memory.h"
#include "core/server/atlas_service.h"

namespace orbatlas {
namespace {

std::uintmax_t file_size_or_zero(const std::filesystem::path& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  return ec ? 0 : size;
}

}  // namespace

HealthReport AtlasService::health() const {
  std::lock_guard lock(mutex_);
  HealthReport out;
  out.shutting_down = shut_down_;
  for (const auto& [_, s] : sessions_) out.live_sessions += s->state() == SessionState::kActive ? 1 : 0;
  out.maps = atlas_.maps().size();
  out.merges_pending = merger_ ? merger_->stats().pending : 0;
  return out;
}

std::vector<prometheus::MetricFamily> AtlasService::metrics() const {
  std::size_t live = 0, stored = 0, worker_errors = 0;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [_, s] : sessions_) {
      const SessionState st = s->state();
      live += st == SessionState::kActive ? 1 : 0;
      stored += st == SessionState::kActive ? 0 : 1;
      worker_errors += s->worker_errors();
    }
  }
  if (merger_) worker_errors += merger_->stats().errors;
  // The shared mappings (sessions count only their own tracking's errors in them).
  std::size_t mapped_keyframes = 0, loops = 0, global_adjustments = 0, stream_end_adjustments = 0, mappers = 0;
  {
    std::lock_guard lock(mappings_mutex_);
    for (const RigMapping& m : mappings_) {
      worker_errors += m.workers->errors();
      mapped_keyframes += m.workers->mapping_stats().keyframes;
      const LoopClosingStats loop = m.workers->loop_stats();
      loops += loop.loops.size();
      global_adjustments += loop.global_adjustments.size();
      stream_end_adjustments +=
          std::count_if(loop.global_adjustments.begin(), loop.global_adjustments.end(),
                        [](const GlobalAdjustmentRun& g) { return g.cause == GlobalAdjustmentCause::kStreamEnd; });
      mappers += m.workers->mapped_maps().size();
    }
  }
  std::size_t keyframes = 0, points = 0;
  const auto maps = atlas_.maps();
  // Per map: what it holds and how many live sessions track in it now (built
  // at each scrape: a merged map's series goes with it).
  prometheus::MetricFamily map_sessions{"orbatlas_map_sessions",
                                        "Live sessions whose last frame was tracked in the map.",
                                        prometheus::MetricType::Gauge,
                                        {}};
  prometheus::MetricFamily map_keyframes{
      "orbatlas_map_keyframes", "Keyframes in the map.", prometheus::MetricType::Gauge, {}};
  for (const auto& m : maps) {
    keyframes += m->keyframe_count();
    points += m->map_point_count();
    const prometheus::ClientMetric::Label label{"map", std::to_string(m->id())};
    prometheus::ClientMetric sessions, kfs;
    sessions.label = {label};
    sessions.gauge.value = static_cast<double>(sessions_in(m->id()).size());
    kfs.label = {label};
    kfs.gauge.value = static_cast<double>(m->keyframe_count());
    map_sessions.metric.push_back(std::move(sessions));
    map_keyframes.metric.push_back(std::move(kfs));
  }
  const CheckpointStats checkpoints = checkpointer_->stats();
  // What is a state, not an event, is read now; totals other parts keep
  // (checkpoints, merges, worker errors) advance their counters to the total.
  std::lock_guard scrape(scrape_mutex_);
  const auto set = [&](const char* name, const char* help, double value) { metrics_.gauge(name, help).Set(value); };
  const auto total = [&](const char* name, const char* help, double value) {
    advance_counter_to(metrics_.counter(name, help), value);
  };
  set("orbatlas_sessions_live", "Sessions taking frames.", static_cast<double>(live));
  set("orbatlas_sessions_ended", "Sessions finished, failed or stored by earlier runs.", static_cast<double>(stored));
  total("orbatlas_worker_errors_total",
        "Errors contained inside tracking, local mapping, loop closing and map merging (the unit of work was given up, "
        "the session and the server went on), over the sessions this server holds.",
        static_cast<double>(worker_errors));
  set("orbatlas_maps", "Maps in the atlas.", static_cast<double>(maps.size()));
  set("orbatlas_keyframes", "Keyframes in the atlas.", static_cast<double>(keyframes));
  set("orbatlas_map_points", "Map points in the atlas.", static_cast<double>(points));
  set("orbatlas_resident_bytes", "Resident memory of the server process (VmRSS).", current_rss_mb() * 1024.0 * 1024.0);
  set("orbatlas_heap_in_use_bytes", "C heap the server holds now (the allocator keeps the rest of the resident heap).",
      heap_in_use_mb() * 1024.0 * 1024.0);
  set("orbatlas_database_bytes", "Size of the atlas database with its write-ahead log.",
      static_cast<double>(file_size_or_zero(options_.db) + file_size_or_zero(options_.db.string() + "-wal")));
  set("orbatlas_local_mappers", "Maps whose local mapping runs now (one thread each).", static_cast<double>(mappers));
  total("orbatlas_mapped_keyframes_total", "Keyframes local mapping has processed.",
        static_cast<double>(mapped_keyframes));
  total("orbatlas_loops_closed_total", "Loops closed in live sessions' maps.", static_cast<double>(loops));
  total("orbatlas_global_adjustments_total",
        "Global bundle adjustments of live sessions' maps: after loops and live merges, of maps several sessions "
        "map (interrupted ones included).",
        static_cast<double>(global_adjustments));
  total("orbatlas_stream_end_adjustments_total",
        "Of those, the ones run when a session ended in a map other sessions mapped too (--finish-refinement-wait).",
        static_cast<double>(stream_end_adjustments));
  total("orbatlas_checkpoints_total", "Checkpoints completed.", static_cast<double>(checkpoints.checkpoints));
  total("orbatlas_checkpoint_failures_total", "Checkpoints that failed (retried).",
        static_cast<double>(checkpoints.failures));
  total("orbatlas_checkpoint_rows_total",
        "Database rows the checkpoints inserted, updated or deleted (maps, keyframes, points, observations, "
        "trajectories, sessions).",
        static_cast<double>(checkpoints.total_rows.total()));
  set("orbatlas_replica_id",
      "This server's id among the replicas of the atlas's database (GET /v1/replicas; 1 for an SQLite atlas).",
      static_cast<double>(replica_->id()));
  total("orbatlas_replica_lease_renewals_total", "Renewals of this replica's lease in a PostgreSQL atlas.",
        static_cast<double>(replica_->renewals()));
  total("orbatlas_replica_lease_renewal_failures_total",
        "Renewals of this replica's lease that failed (the database unreachable; retried).",
        static_cast<double>(replica_->failed_renewals()));
  set("orbatlas_replica_lease_lost",
      "1 when this replica's lease passed before it was renewed (others may hold what it held).",
      replica_->lease_lost() ? 1.0 : 0.0);
  if (merger_) {
    const MapMergeWorkerStats merging = merger_->stats();
    std::size_t live_merged = 0;
    {
      std::lock_guard lock(live_merges_mutex_);
      live_merged = live_merges_total_;
    }
    total("orbatlas_map_merges_total",
          "Maps merged into another map since the server started (live and at a session's end).",
          static_cast<double>(merging.merges_total + live_merged));
    set("orbatlas_map_merge_pending", "Maps waiting for (or in) the merging worker.",
        static_cast<double>(merging.pending));
  }
  std::vector<prometheus::MetricFamily> out = metrics_.collect();
  out.push_back(std::move(map_sessions));
  out.push_back(std::move(map_keyframes));
  return out;
}

}  // namespace orbatlas
