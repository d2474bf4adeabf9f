#pragma once
// The map service's figures for GET /metrics: events counted as they happen
// (sessions created and timed out, frames tracked, refused and skipped, their
// latencies, live poses' jumps, localisations), and, at each scrape, the
// service's state as the facade read it (ServiceState: sessions, maps,
// mapping, checkpoints, replica, merging). Thread-safe; scrapes are serialised
// (totals kept elsewhere advance their counters).
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "core/common/ids.h"
#include "core/persistence/atlas_checkpointer.h"
#include "core/server/metrics_registry.h"

namespace orbatlas {

// What the service is now, read by AtlasService for a scrape.
struct ServiceState {
  std::size_t live_sessions = 0, ended_sessions = 0, worker_errors = 0;
  std::size_t mapped_keyframes = 0, loops = 0, global_adjustments = 0, stream_end_adjustments = 0, mappers = 0;
  std::size_t keyframes = 0, map_points = 0;
  struct MapState {
    MapId map = 0;
    std::size_t keyframes = 0, sessions = 0;  // live sessions whose last frame was tracked in it
  };
  std::vector<MapState> maps;
  std::uintmax_t database_bytes = 0;
  CheckpointStats checkpoints;
  std::uint64_t replica_id = 0, lease_renewals = 0, lease_renewal_failures = 0;
  bool lease_lost = false;
  struct Merging {
    std::size_t merges_total = 0, pending = 0;  // live merges and the worker's
  };
  std::optional<Merging> merging;  // none when merging is off
};

class ServiceMetrics {
 public:
  ServiceMetrics();
  ServiceMetrics(const ServiceMetrics&) = delete;
  ServiceMetrics& operator=(const ServiceMetrics&) = delete;

  void session_created() { sessions_created_.Increment(); }
  void session_timed_out() { sessions_timed_out_.Increment(); }
  void frame_rejected() { frames_rejected_.Increment(); }
  void frame_skipped() { frames_skipped_.Increment(); }
  void frame_maps_busy() { frames_maps_busy_.Increment(); }
  // A tracked frame: its tracking and its whole time in the server.
  void frame_done(double tracking_ms, double request_ms);
  void live_pose_jump(double m) { live_pose_jumps_.Observe(m); }
  void localized(bool recognised, double ms);

  // Every family: the counters and histograms, the state's gauges and totals,
  // and the per-map families built from `now`.
  std::vector<prometheus::MetricFamily> collect(const ServiceState& now);

 private:
  MetricsRegistry registry_;
  std::mutex scrape_mutex_;  // one collect() at a time (totals advance counters)
  prometheus::Counter& sessions_created_;
  prometheus::Counter& sessions_timed_out_;
  prometheus::Counter& frames_;
  prometheus::Counter& frames_rejected_;
  prometheus::Counter& frames_skipped_;
  prometheus::Counter& frames_maps_busy_;
  prometheus::Histogram& tracking_latency_;
  prometheus::Histogram& frame_request_latency_;
  prometheus::Histogram& live_pose_jumps_;
  prometheus::Counter& localize_requests_;
  prometheus::Counter& localize_recognised_;
  prometheus::Histogram& localize_latency_;
};

}  // namespace orbatlas
