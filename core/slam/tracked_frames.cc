#include "core/slam/tracked_frames.h"

#include <chrono>
#include <string>

#include "core/common/stopwatch.h"

namespace orbatlas {

TrackResult TrackedFrames::track(Tracker& tracker, Frame frame, const Atlas& atlas,
                                 std::chrono::steady_clock::time_point started, double max_maps_wait_ms) {
  const TimestampNs t_ns = frame.t_ns;
  TrackResult result;
  double maps_wait_ms = 0.0;
  try {
    const auto waiting = std::chrono::steady_clock::now();
    const auto whole =
        max_maps_wait_ms > 0.0
            ? atlas.lock_maps_shared_until(waiting + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                         std::chrono::duration<double, std::milli>(max_maps_wait_ms)))
            : atlas.lock_maps_shared();
    maps_wait_ms = ms_since(waiting);
    if (!whole.owns_lock()) {
      result.t_ns = t_ns;
      result.state = tracker.state();
      result.maps_busy = true;
      result.maps_wait_ms = maps_wait_ms;
      maps_wait_ms_.add(maps_wait_ms);
      ++maps_busy_;
      ++frames_;
      return result;
    }
    const std::uint64_t edits = atlas.maps_edits();  // stable while the maps are held shared
    result = tracker.track(std::move(frame));
    result.maps_edits = edits;
    errors_.succeeded();
  } catch (const DataError&) {
    throw;  // the frame's fault: the caller says so to the user
  } catch (const WorkerFailed&) {
    throw;
  } catch (...) {
    if (errors_.record("frame at " + std::to_string(t_ns) + " ns", std::current_exception())) throw;
    result = TrackResult{};
    result.t_ns = t_ns;
    result.state = tracker.state();
  }
  result.maps_wait_ms = maps_wait_ms;
  maps_wait_ms_.add(maps_wait_ms);
  tracking_ms_.add(ms_since(started));
  if (result.local_points > 0) {
    local_keyframes_.add(result.local_keyframes);
    local_points_.add(result.local_points);
  }
  ++frames_;
  if (result.tracked && tracker.last_anchor()) {
    std::lock_guard lock(anchors_mutex_);
    anchors_.push_back(*tracker.last_anchor());
  }
  if (result.tracked) ++(result.by_imu ? tracked_by_imu_ : tracked_);
  return result;
}

void TrackedFrames::report(SlamStats& stats) const {
  stats.tracking_ms = tracking_ms_;
  stats.local_map_keyframes = local_keyframes_;
  stats.local_map_points = local_points_;
  stats.maps_wait_ms = maps_wait_ms_;
  stats.maps_busy_frames = maps_busy_;
}

std::vector<FrameAnchor> TrackedFrames::anchors_from(std::size_t first) const {
  std::lock_guard lock(anchors_mutex_);
  if (first >= anchors_.size()) return {};
  return {anchors_.begin() + static_cast<std::ptrdiff_t>(first), anchors_.end()};
}

std::optional<FrameAnchor> TrackedFrames::last_anchor() const {
  std::lock_guard lock(anchors_mutex_);
  if (anchors_.empty()) return std::nullopt;
  return anchors_.back();
}

}  // namespace orbatlas
