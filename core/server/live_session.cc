#include "core/server/live_session.h"

#include <chrono>
#include <cmath>

#include "core/common/log.h"
#include "core/server/service_error.h"
#include "core/slam/slam_stats.h"

namespace orbatlas {

const char* session_mode_name(SessionMode mode) { return mode == SessionMode::kLocalize ? "localize" : "map"; }

const char* session_state_name(SessionState state) {
  switch (state) {
    case SessionState::kActive:
      return "active";
    case SessionState::kFinished:
      return "finished";
    case SessionState::kFailed:
      return "failed";
    case SessionState::kStored:
      return "stored";
  }
  return "?";
}

LiveSession::LiveSession(SessionInfo info, std::string config, std::unique_ptr<SessionSlam> slam, SessionMode mode,
                         std::optional<double> max_lag_s)
    : info_(std::move(info)),
      config_(std::move(config)),
      mode_(mode),
      slam_(std::move(slam)),
      state_(SessionState::kActive),
      max_lag_ns_(max_lag_s ? std::optional<std::int64_t>(s_to_ns(*max_lag_s)) : std::nullopt) {}

namespace {

std::optional<SessionMode> stored_mode(const std::optional<SessionRecord>& record) {
  if (!record || record->mode.empty()) return std::nullopt;
  return record->mode == "localize" ? SessionMode::kLocalize : SessionMode::kMap;
}

}  // namespace

LiveSession::LiveSession(SessionInfo info, const std::optional<SessionRecord>& record,
                         const std::vector<FrameAnchor>& trajectory)
    : info_(std::move(info)),
      config_(record ? record->config : std::string()),
      mode_(stored_mode(record)),
      state_(SessionState::kStored),
      anchors_released_(true),
      last_anchor_(trajectory.empty() ? std::nullopt : std::optional<FrameAnchor>(trajectory.back())) {
  if (!record) {
    frames_ = tracked_ = trajectory.size();
    return;
  }
  frames_ = record->frames;
  tracked_ = record->tracked;
  keyframes_ = record->keyframes;
  rejected_frames_ = record->rejected_frames;
  skipped_frames_ = record->skipped_frames;
  maps_busy_frames_ = record->maps_busy_frames;
  imu_samples_ = record->imu_samples;
  error_ = record->error;
  // A session the last checkpoint saw running: the server stopped before its end was stored.
  ended_by_ = record->outcome == "active" ? std::string("interrupted") : record->ended_by;
}

LiveSession::~LiveSession() {
  try {
    finish();
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(info_.id) + ": " + e.what());
  }
}

void LiveSession::fail(const std::string& why) {
  state_ = SessionState::kFailed;
  error_ = why;
  log_warn("session " + std::to_string(info_.id) + " failed: " + why);
  if (slam_) {
    worker_errors_.store(slam_->worker_errors());
    final_anchors_ = slam_->anchors();
    try {
      final_imu_warnings_ = slam_->imu_warnings();
    } catch (const std::exception&) {
      // A failed session's warnings are a detail; its error says what went wrong.
    }
    slam_.reset();  // stops its threads (errors are logged there); the maps stay in the atlas
  }
}

FrameOutcome LiveSession::process(TimestampNs t_ns, const cv::Mat& left, const cv::Mat& right) {
  std::lock_guard lock(mutex_);
  last_activity_.store(std::chrono::steady_clock::now().time_since_epoch().count());
  if (state_ != SessionState::kActive)
    throw_conflict("session " + std::to_string(info_.id) + " is " + session_state_name(state_) +
                   (error_.empty() ? "" : " (" + error_ + ")") + "; it takes no more frames");
  if (!is_valid_timestamp(t_ns)) {
    ++rejected_frames_;
    throw DataError(invalid_timestamp_message("frame timestamp", t_ns));
  }
  if (last_frame_t_ && t_ns <= *last_frame_t_) {
    ++rejected_frames_;
    throw DataError("frame timestamp " + std::to_string(t_ns) + " ns is not after the previous frame's (" +
                    std::to_string(*last_frame_t_) + " ns)");
  }
  FrameOutcome out;
  const auto start = std::chrono::steady_clock::now();
  if (max_lag_ns_) {
    // Arrival minus capture, against the smallest seen: how far behind the
    // sensor this frame is (the network's and the client's constant delays cancel).
    const std::int64_t offset =
        std::chrono::duration_cast<std::chrono::nanoseconds>(start.time_since_epoch()).count() - t_ns;
    if (!min_offset_ns_ || offset < *min_offset_ns_) min_offset_ns_ = offset;
    if (offset - *min_offset_ns_ > *max_lag_ns_) {
      last_frame_t_ = t_ns;  // timestamps still increase across skipped frames
      ++skipped_frames_;
      out.skipped = true;
      out.result.t_ns = t_ns;
      if (last_) out.result.state = last_->state;
      return out;
    }
  }
  try {
    out.result = slam_->process(t_ns, left, right);
  } catch (const DataError&) {
    ++rejected_frames_;
    throw;
  } catch (const std::exception& e) {
    fail(e.what());
    throw ServiceError(ServiceErrorKind::kFailed, "session_failed",
                       "session " + std::to_string(info_.id) + " failed: " + e.what());
  }
  out.tracking_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  worker_errors_.store(slam_->worker_errors());
  last_frame_t_ = t_ns;
  ++frames_;
  if (out.result.tracked && !out.result.by_imu) ++tracked_;  // the slam stats count the IMU's frames
  if (out.result.keyframe) ++keyframes_;
  if (out.result.maps_busy) ++maps_busy_frames_;
  tracking_ms_.add(out.tracking_ms);
  maps_wait_ms_.add(out.result.maps_wait_ms);
  // Answered untracked because the maps were held too long: the tracker has
  // not seen the frame, and the session's pose and map stay those of the last.
  if (out.result.maps_busy) return out;
  if (out.result.tracked) {
    out.jump_m = pose_jumps_.add(out.result.T_w_b.t, out.result.map, out.result.maps_edits);
    if (out.jump_m) live_jumps_m_.add(*out.jump_m);
  } else {
    pose_jumps_.lost();
  }
  last_ = out.result;
  current_map_.store(out.result.tracked ? out.result.map : kInvalidMapId);
  if (out.result.tracked && out.result.map != logged_map_) {
    // The session's map lineage in the log (a map started or joined, a merge
    // into another): rare, and what explains a session's accuracy in a shared map.
    log_info("session " + std::to_string(info_.id) + " (" + info_.name + ") tracks in map " +
             std::to_string(out.result.map) +
             (logged_map_ == kInvalidMapId ? std::string() : " (was map " + std::to_string(logged_map_) + ")") +
             " at frame " + std::to_string(frames_) + ", " + std::to_string(out.result.t_ns) + " ns");
    logged_map_ = out.result.map;
  }
  return out;
}

void LiveSession::note_request(double decode_ms, double request_ms) {
  std::lock_guard lock(mutex_);
  decode_ms_.add(decode_ms);
  request_ms_.add(request_ms);
}

std::size_t LiveSession::add_imu(const std::vector<ImuSample>& samples) {
  std::lock_guard lock(mutex_);
  if (state_ != SessionState::kActive)
    throw_conflict("session " + std::to_string(info_.id) + " is " + session_state_name(state_) + "; it takes no IMU");
  // The stream's order is the protocol's (a batch out of order is refused
  // whole); what the values carry (not finite, a stuck axis, saturation, gaps)
  // the session judges and reports in its status (SessionSlam::imu_warnings).
  std::optional<TimestampNs> previous = last_imu_t_;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const ImuSample& s = samples[i];
    if (!is_valid_timestamp(s.t_ns))
      throw DataError(invalid_timestamp_message("IMU sample " + std::to_string(i) + " at", s.t_ns));
    if (previous && s.t_ns <= *previous)
      throw DataError("IMU sample " + std::to_string(i) + " at " + std::to_string(s.t_ns) +
                      " ns is not after the previous sample (" + std::to_string(*previous) + " ns)");
    previous = s.t_ns;
    // NaN passes (a real IMU's dropout, judged by the session); magnitudes no sensor gives do not.
    const double gyro = s.gyro.cwiseAbs().maxCoeff(), accel = s.accel.cwiseAbs().maxCoeff();
    if (gyro > kMaxImuGyro || accel > kMaxImuAccel)
      throw DataError("IMU sample " + std::to_string(i) + " at " + std::to_string(s.t_ns) + " ns reads " +
                      (gyro > kMaxImuGyro ? std::to_string(gyro) + " rad/s" : std::to_string(accel) + " m/s^2") +
                      ": beyond any IMU's range (" + std::to_string(static_cast<int>(kMaxImuGyro)) + " rad/s, " +
                      std::to_string(static_cast<int>(kMaxImuAccel)) + " m/s^2)");
  }
  slam_->add_imu(samples);  // a session that fuses its IMU (stereo-inertial) keeps them; others ignore them
  last_imu_t_ = previous;
  imu_samples_ += samples.size();
  return samples.size();
}

bool LiveSession::finish() { return finish(std::string()); }

bool LiveSession::finish(const std::string& ended_by) {
  std::function<bool()> refine;  // run once the session's lock is released
  {
    std::lock_guard lock(mutex_);
    if (!finish_locked(ended_by, refine)) return false;
  }
  try {
    // Status reads and the checkpoints' reads of the session do not wait for it.
    if (refine) refine();
  } catch (const std::exception& e) {
    log_warn("session " + std::to_string(info_.id) + ": the global BA of its map at its end failed: " + e.what());
  }
  return true;
}

bool LiveSession::finish_locked(const std::string& ended_by, std::function<bool()>& refine) {
  if (state_ != SessionState::kActive) return false;
  ended_by_ = ended_by;
  try {
    slam_->finish();
    refine = slam_->take_end_refinement();
    worker_errors_.store(slam_->worker_errors());
    const SlamStats stats = slam_->stats();
    final_counts_ = SessionStatus::SlamCounts{
        stats.relocalizations,    stats.loop.loops.size(), stats.imu_initialized_at_s, stats.imu_bias,
        stats.imu_time_offset_ms, stats.imu_white_noise,   stats.mapping_wait_ms,      stats.mapping_waits_cut};
    final_anchors_ = slam_->anchors();
    final_imu_warnings_ = slam_->imu_warnings();
    slam_.reset();
    state_ = SessionState::kFinished;
  } catch (const std::exception& e) {
    fail(e.what());
    throw ServiceError(ServiceErrorKind::kFailed, "session_failed",
                       "session " + std::to_string(info_.id) + " failed while finishing: " + e.what());
  }
  return true;
}

std::vector<FrameAnchor> LiveSession::anchors_from(std::size_t first) const {
  std::lock_guard lock(mutex_);
  if (slam_) return slam_->anchors_from(first);
  if (first >= final_anchors_.size()) return {};
  return {final_anchors_.begin() + static_cast<std::ptrdiff_t>(first), final_anchors_.end()};
}

bool LiveSession::has_anchors() const {
  std::lock_guard lock(mutex_);
  return !anchors_released_;
}

std::optional<FrameAnchor> LiveSession::last_anchor() const {
  std::lock_guard lock(mutex_);
  if (anchors_released_) return last_anchor_;
  if (!slam_) return final_anchors_.empty() ? std::nullopt : std::optional<FrameAnchor>(final_anchors_.back());
  return slam_->last_anchor();
}

void LiveSession::release_anchors() {
  std::lock_guard lock(mutex_);
  if (slam_ || anchors_released_) return;  // still running, or already
  if (!final_anchors_.empty()) last_anchor_ = final_anchors_.back();
  std::vector<FrameAnchor>().swap(final_anchors_);
  anchors_released_ = true;
}

SessionRecord LiveSession::record() const {
  std::lock_guard lock(mutex_);
  SessionRecord r;
  r.frames = frames_;
  r.tracked = tracked_;
  r.keyframes = keyframes_;
  r.rejected_frames = rejected_frames_;
  r.skipped_frames = skipped_frames_;
  r.maps_busy_frames = maps_busy_frames_;
  r.imu_samples = imu_samples_;
  r.mode = mode_ ? session_mode_name(*mode_) : "";
  r.config = config_;
  const SessionState state = state_.load();
  r.outcome = state == SessionState::kFailed ? "failed" : state == SessionState::kActive ? "active" : "finished";
  r.ended_by = ended_by_;
  r.error = error_;
  return r;
}

SessionStatus LiveSession::status() const {
  std::lock_guard lock(mutex_);
  SessionStatus s;
  s.id = info_.id;
  s.name = info_.name;
  s.state = state_;
  s.sensor = info_.sensor;
  s.mode = mode_;
  s.frames = frames_;
  s.tracked = tracked_;
  s.keyframes = keyframes_;
  s.rejected_frames = rejected_frames_;
  s.skipped_frames = skipped_frames_;
  s.maps_busy_frames = maps_busy_frames_;
  s.imu_samples = imu_samples_;
  s.worker_errors = worker_errors_.load();
  s.imu_warnings = slam_ ? slam_->imu_warnings() : final_imu_warnings_;
  s.config = config_;
  s.error = error_;
  s.ended_by = ended_by_;
  if (last_) {
    s.map = last_->map;
    s.last_frame = SessionStatus::LastFrame{last_->t_ns, last_->tracked};
  }
  s.tracking_ms = tracking_ms_;
  s.live_jumps_m = live_jumps_m_;
  s.request_ms = request_ms_;
  s.decode_ms = decode_ms_;
  s.maps_wait_ms = maps_wait_ms_;
  s.slam = final_counts_;
  return s;
}

}  // namespace orbatlas
