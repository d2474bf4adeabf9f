#pragma once
// The per-frame bookkeeping a session shares between its tracking thread and
// readers on other threads (SlamSystem and MonoLocalizer): tracking one frame
// with its errors contained, the time it took, frame counts, and the anchors of
// the tracked frames.
//
// An error inside tracking that is not the frame's fault (not a DataError) is
// a broken invariant of the engine: the frame is reported as not tracked, the
// error is logged and counted (stats: worker_errors, tracking), and the next
// frame is tracked as usual. Only a run of such errors, or a worker that gave
// up on the map (WorkerFailed), fails the session.
#include <chrono>
#include <deque>
#include <cstddef>
#include <mutex>
#include <optional>
#include <vector>

#include "core/common/sample_summary.h"
#include "core/common/worker_errors.h"
#include "core/map/atlas.h"
#include "core/map/frame_anchor.h"
#include "core/slam/slam_stats.h"
#include "core/tracking/tracker.h"

namespace orbatlas {

class TrackedFrames {
 public:
  // Tracks `frame` with `tracker`, holding `atlas`'s maps shared: the frame
  // sees every map before or after an edit of loop closing or merging, never
  // half-way (those hold them exclusive); `started`: when the frame's
  // processing began (its front end included). With `max_maps_wait_ms` above
  // 0, a frame that cannot have the maps within that long is not tracked: its
  // result says maps_busy (the tracker has not seen it).
  // Rethrows DataError (the frame's fault), WorkerFailed, and the error that
  // makes tracking fail too many times in a row.
  TrackResult track(Tracker& tracker, Frame frame, const Atlas& atlas, std::chrono::steady_clock::time_point started,
                    double max_maps_wait_ms = 0.0);

  std::vector<FrameAnchor> anchors_from(std::size_t first) const;  // the first-th on; any thread
  std::vector<FrameAnchor> anchors() const { return anchors_from(0); }
  std::optional<FrameAnchor> last_anchor() const;  // any thread; none before a tracked frame
  std::size_t frames() const { return frames_; }
  std::size_t tracked() const { return tracked_; }                // visually
  std::size_t tracked_by_imu() const { return tracked_by_imu_; }  // by the IMU alone (they have anchors too)
  std::size_t maps_busy() const { return maps_busy_; }            // not tracked: the maps were held too long
  // The per-frame figures into `stats`: tracking_ms, the local maps' keyframes
  // and projected points (frames tracked in one), the waits for the maps and
  // the frames not tracked for them.
  void report(SlamStats& stats) const;
  WorkerErrorCounts errors() const { return errors_.counts(); }

 private:
  WorkerErrors errors_{"tracking"};
  SampleSummary tracking_ms_;
  SampleSummary local_keyframes_, local_points_, maps_wait_ms_;
  std::size_t frames_ = 0, tracked_ = 0, tracked_by_imu_ = 0, maps_busy_ = 0;
  mutable std::mutex anchors_mutex_;
  std::deque<FrameAnchor> anchors_;  // one per tracked frame, for other threads (a deque: no copy as it grows)
};

}  // namespace orbatlas
