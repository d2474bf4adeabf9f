#pragma once
// One client session of the server: its own SLAM (tracking on the request's
// thread, local mapping and loop closing on their own) or, for a single
// camera, its own localisation in the stored maps; serialised per session,
// with what the API reports about it. A session from an earlier run of the
// server (read from the database) is a LiveSession without SLAM, state "stored".
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/common/sample_summary.h"
#include "core/eval/live_pose_jumps.h"
#include "core/io/euroc_types.h"
#include "core/map/frame_anchor.h"
#include "core/persistence/session_info.h"
#include "core/persistence/session_record.h"
#include "core/server/service_results.h"
#include "core/slam/session_slam.h"

namespace orbatlas {

struct FrameOutcome {
  TrackResult result;
  double tracking_ms = 0.0;  // inside SlamSystem::process (features + tracking)
  bool skipped = false;      // arrived too late (max_lag_s): not tracked
  // The first frame after a whole-map correction: how far its pose jumped from
  // where the frames before predicted it (core/eval/live_pose_jumps.h).
  std::optional<double> jump_m;
};

class LiveSession {
 public:
  // `max_lag_s`: a frame that arrives more than this behind the session's
  // sensor clock is skipped (see process()); none: every frame is tracked.
  LiveSession(SessionInfo info, std::string config, std::unique_ptr<SessionSlam> slam,
              SessionMode mode = SessionMode::kMap, std::optional<double> max_lag_s = std::nullopt);
  // A stored session (an earlier run's): what its last checkpoint recorded
  // (none for sessions stored before schema 16: then the frames are those of its
  // trajectory); only the trajectory's last frame is kept (the rest stays in the database).
  LiveSession(SessionInfo info, const std::optional<SessionRecord>& record, const std::vector<FrameAnchor>& trajectory);
  ~LiveSession();
  LiveSession(const LiveSession&) = delete;
  LiveSession& operator=(const LiveSession&) = delete;

  SessionId id() const { return info_.id; }
  std::optional<SessionMode> mode() const { return mode_; }  // none for a stored session
  // The map its last frame was tracked in (kInvalidMapId: none, or not active); lock-free.
  MapId current_map() const { return state_.load() == SessionState::kActive ? current_map_.load() : kInvalidMapId; }
  const SessionInfo& info() const { return info_; }
  SessionState state() const { return state_.load(); }  // never waits for a frame or a finish

  // One stereo pair, or one image (`right` empty) for a single-camera session. ServiceError 409 when the session is not
  // active; DataError for a bad frame (timestamp not after the previous one, wrong size...): the session goes on. Any
  // other failure of tracking or mapping fails the session (state "failed", ServiceError 500 naming the cause); the
  // server goes on. With a largest lag, a frame whose arrival is more than it
  // behind its timestamp, measured against the earliest arrival seen (the
  // frame that came soonest after its capture sets the clock offset), is
  // skipped: not tracked, counted (`skipped_frames`), the reply says so. A
  // frame whose session may wait only so long for the maps
  // (SlamSystemOptions::max_maps_wait_ms) and could not have them is answered
  // untracked (`maps_busy`, counted in `maps_busy_frames`).
  FrameOutcome process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right);
  // A batch of IMU samples, checked (valid stamps, strictly increasing across
  // batches; values no IMU measures, beyond kMaxImuGyro / kMaxImuAccel: DataError
  // otherwise, and then none of the batch is taken), counted and handed to the
  // session, which drops what it cannot use (saturation at the sensor's own
  // range included) and says so in the status's imu_warnings (sessions without
  // an IMU ignore them). IMU alone does not keep a session from its idle timeout.
  std::size_t add_imu(const std::vector<ImuSample>& samples);
  // Lets mapping finish what is queued, stops it and drops the SLAM objects
  // (the frames' anchors stay). Idempotent; false when it was not active.
  bool finish();
  // finish() on behalf of the server, saying why ("idle_timeout"), shown in the status.
  bool finish(const std::string& ended_by);
  // Bounds on the values of an IMU sample: above any MEMS sensor's range
  // (gyroscopes to about 70 rad/s, accelerometers to about 200 g).
  static constexpr double kMaxImuGyro = 100.0;    // rad/s
  static constexpr double kMaxImuAccel = 2000.0;  // m/s^2
  // When the client last sent a frame (or created the session).
  std::chrono::steady_clock::time_point last_activity() const {
    return std::chrono::steady_clock::time_point(std::chrono::steady_clock::duration(last_activity_.load()));
  }

  // The tracked frames' anchors while they are in memory (thread-safe); empty
  // once stored and released (has_anchors() false): read them from the database.
  std::vector<FrameAnchor> anchors() const { return anchors_from(0); }
  std::vector<FrameAnchor> anchors_from(std::size_t first) const;  // the first-th on
  bool has_anchors() const;
  std::optional<FrameAnchor> last_anchor() const;
  // An ended session whose trajectory is stored: drop the anchors from memory,
  // keep the count and the last one (a long-running server keeps the same few
  // hundred bytes per ended session).
  void release_anchors();
  // Errors the session's workers contained (as of its last frame; any thread).
  std::size_t worker_errors() const { return worker_errors_.load(); }
  SessionStatus status() const;  // GET /v1/sessions/{id}
  // A tracked frame's request as the server handled it: its images' decoding and
  // its whole time from the request's handling to the reply (status: decode_ms, request_ms).
  void note_request(double decode_ms, double request_ms);
  // What the database keeps of it (counts, mode, config, how it ended); any thread.
  SessionRecord record() const;

 private:
  void fail(const std::string& why);  // under mutex_

  const SessionInfo info_;
  const std::string config_;
  const std::optional<SessionMode> mode_;  // none for a stored session of an older database
  // finish() under mutex_: the SLAM objects go; `refine` gets what is left to
  // wait for (SessionSlam::take_end_refinement), run after the lock is released.
  bool finish_locked(const std::string& ended_by, std::function<bool()>& refine);
  mutable std::mutex mutex_;  // serialises frames, IMU and finish
  std::unique_ptr<SessionSlam> slam_;
  // Written under mutex_; read without it (state()), so asking a session for its
  // state never waits for its frame or its finish (docs/architecture.md, locks).
  std::atomic<SessionState> state_;
  std::string error_;
  std::vector<FrameAnchor> final_anchors_;  // once the SLAM objects are gone, until released
  bool anchors_released_ = false;
  std::optional<FrameAnchor> last_anchor_;  // kept when released
  std::optional<TimestampNs> last_frame_t_, last_imu_t_;
  std::size_t frames_ = 0, tracked_ = 0, keyframes_ = 0, rejected_frames_ = 0, imu_samples_ = 0, skipped_frames_ = 0,
              maps_busy_frames_ = 0;
  const std::optional<std::int64_t> max_lag_ns_;
  std::optional<std::int64_t> min_offset_ns_;  // smallest arrival - timestamp seen
  std::optional<TrackResult> last_;
  SampleSummary tracking_ms_;
  SampleSummary request_ms_, decode_ms_, maps_wait_ms_;    // under mutex_
  LivePoseJumps pose_jumps_;                               // under mutex_
  SampleSummary live_jumps_m_;                             // under mutex_
  std::optional<SessionStatus::SlamCounts> final_counts_;  // captured by finish()
  std::vector<std::string> final_imu_warnings_;            // captured by finish() or fail()
  std::atomic<std::size_t> worker_errors_{0};
  std::atomic<MapId> current_map_{kInvalidMapId};
  MapId logged_map_ = kInvalidMapId;  // under mutex_: the last map the log named for this session
  std::atomic<std::chrono::steady_clock::rep> last_activity_{
      std::chrono::steady_clock::now().time_since_epoch().count()};
  std::string ended_by_;  // under mutex_; empty: the client finished it
};

}  // namespace orbatlas
