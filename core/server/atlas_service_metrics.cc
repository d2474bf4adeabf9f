// AtlasService: what the server reports about itself: GET /healthz and the
// state GET /metrics shows (ServiceMetrics turns it into families).
#include <filesystem>
#include <string>
#include <vector>

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
  HealthReport out;
  out.shutting_down = sessions_.stopped();
  out.live_sessions = sessions_.counts().live;
  out.maps = atlas_.maps().size();
  out.merges_pending = merger_ ? merger_->stats().pending : 0;
  return out;
}

std::vector<prometheus::MetricFamily> AtlasService::metrics() const {
  ServiceState now;
  const SessionRegistry::Counts counts = sessions_.counts();
  now.live_sessions = counts.live;
  now.ended_sessions = counts.ended;
  now.worker_errors = counts.worker_errors;
  if (merger_) now.worker_errors += merger_->stats().errors;
  // The shared mappings (sessions count only their own tracking's errors in them).
  const RigMappings::Totals mapping = mappings_.totals();
  now.worker_errors += mapping.errors;
  now.mapped_keyframes = mapping.mapped_keyframes;
  now.loops = mapping.loops;
  now.global_adjustments = mapping.global_adjustments;
  now.stream_end_adjustments = mapping.stream_end_adjustments;
  now.mappers = mapping.mappers;
  for (const auto& m : atlas_.maps()) {
    now.keyframes += m->keyframe_count();
    now.map_points += m->map_point_count();
    now.maps.push_back({m->id(), m->keyframe_count(), sessions_.in_map(m->id()).size()});
  }
  now.database_bytes = file_size_or_zero(options_.db) + file_size_or_zero(options_.db.string() + "-wal");
  now.checkpoints = checkpointer_->stats();
  now.replica_id = replica_->id();
  now.lease_renewals = replica_->renewals();
  now.lease_renewal_failures = replica_->failed_renewals();
  now.lease_lost = replica_->lease_lost();
  if (merger_) {
    std::size_t live_merged = 0;
    {
      std::lock_guard lock(live_merges_mutex_);
      live_merged = live_merges_total_;
    }
    const MapMergeWorkerStats merging = merger_->stats();
    now.merging = ServiceState::Merging{merging.merges_total + live_merged, merging.pending};
  }
  return metrics_.collect(now);
}

}  // namespace orbatlas
