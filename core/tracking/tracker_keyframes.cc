// The tracker's keyframes (ORB-SLAM's NeedNewKeyFrame and CreateNewKeyFrame):
// when a frame becomes one, the keyframe made from it and filled with points,
// and tracking's wait for local mapping to adjust it.
#include <chrono>
#include <utility>

#include "core/tracking/keyframe_points.h"
#include "core/tracking/tracker.h"

namespace orbatlas {

bool Tracker::observed_by_own_keyframe(const MapPoint& point) const {
  bool own = false;
  point.for_each_observer(
      [&](KeyframeId id, const std::weak_ptr<KeyFrame>&) { own = own || own_keyframes_.contains(id); });
  return own;
}

bool Tracker::need_new_keyframe(const Frame& frame, int inliers) const {
  if (options_.localization_only || !reference_ || !sink_.accepting(map_->id())) return false;
  if (options_.max_keyframe_interval_s > 0.0 && last_keyframe_ &&
      ns_to_s(frame.t_ns - last_keyframe_->timestamp_ns()) >= options_.max_keyframe_interval_s && inliers > 15 &&
      sink_.queued(map_->id()) < 3)
    return true;
  const std::size_t n_kfs = map_->keyframe_count();
  // Observing keyframes; ORB-SLAM counts a stereo observation twice (its 3, or
  // 2 in a map of two keyframes).
  const int min_obs = monocular_ ? (n_kfs <= 2 ? 2 : 3) : (n_kfs <= 2 ? 1 : 2);
  int ref_matches = 0;
  reference_->for_each_map_point([&](const std::shared_ptr<MapPoint>& mp) {
    if (!mp->is_bad() && mp->observation_count() >= static_cast<std::size_t>(min_obs)) ++ref_matches;
  });

  int tracked_close = 0, untracked_close = 0;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const float z = frame.depth[i];
    if (z <= 0.0f || z >= options_.th_depth_m) continue;
    if (tracked_close >= 100) break;  // need_close is false whatever follows
    if (frame.map_points[i] && !frame.outlier[i]) {
      if (options_.own_close_points && !observed_by_own_keyframe(*frame.map_points[i])) {
        ++untracked_close;  // a keyframe here adds this session's observation of it
        continue;
      }
      ++tracked_close;
    } else {
      ++untracked_close;
    }
  }
  const bool need_close = tracked_close < 100 && untracked_close > 70;
  const double ref_ratio = monocular_ ? 0.9 : n_kfs < 2 ? 0.4 : 0.75;
  const bool idle = sink_.idle(map_->id());
  const bool c1a = frame_index_ >= last_keyframe_index_ + options_.max_frames_between_keyframes;
  const bool c1b = idle;
  const bool c1c = inliers < ref_matches * 0.25 || need_close;
  const bool c2 = (inliers < ref_matches * ref_ratio || need_close) && inliers > 15;
  if (!((c1a || c1b || c1c) && c2)) return false;
  if (idle) return true;
  sink_.interrupt_optimization(map_->id());
  // A single camera waits for local mapping (its new points come from
  // triangulation there, not from this frame's depth).
  return !monocular_ && sink_.queued(map_->id()) < 3;
}

std::shared_ptr<KeyFrame> Tracker::new_keyframe(Frame& frame) {
  ensure_bow(frame);
  KeyFrameData data;
  data.timestamp_ns = frame.t_ns;
  data.T_w_b = frame.T_w_b;
  data.T_b_c = T_b_c_;
  data.features = frame.features;
  data.depth = frame.depth;
  data.u_right = frame.u_right;
  data.bow = frame.bow;
  data.feature_vector = frame.feature_vector;
  data.grid = frame.grid;
  return map_->new_keyframe(std::move(data));
}

void Tracker::keyframe_made(std::shared_ptr<KeyFrame> kf) {
  if (keyframe_listener_) keyframe_listener_(kf, last_keyframe_);
  reference_ = kf;
  last_keyframe_ = kf;
  own_keyframes_.insert(kf->id());
  last_keyframe_index_ = frame_index_;
  awaiting_adjustment_ = kf->map_id();
  sink_.insert(std::move(kf));
}

std::optional<double> Tracker::wait_for_mapping() {
  const std::optional<MapId> map = std::exchange(awaiting_adjustment_, std::nullopt);
  if (!map || options_.max_mapping_wait_ms <= 0.0) return std::nullopt;
  const auto start = std::chrono::steady_clock::now();
  const auto at_most = std::chrono::duration_cast<std::chrono::milliseconds>(
      std::chrono::duration<double, std::milli>(options_.max_mapping_wait_ms));
  const bool adjusted = sink_.wait_until_adjusted(*map, at_most);
  const double waited = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (!adjusted) {
    ++mapping_waits_cut_;
    // Still not adjusted after the whole bound: the next frame waits again (at
    // most as long), so a local BA longer than one wait is still waited for, a
    // frame at a time. (A paused mapping answers at once: nothing to wait for.)
    if (waited >= static_cast<double>(at_most.count())) awaiting_adjustment_ = map;
  }
  return waited;
}

void Tracker::create_keyframe(Frame& frame, bool all_stereo_points) {
  auto kf = new_keyframe(frame);
  KeyframePointsOptions points;
  points.th_depth_m = options_.th_depth_m;
  points.all_stereo_points = all_stereo_points;
  // Local mapping may already be editing the keyframe's slots (see keyframe_points.h).
  const KeyframePointsResult added = add_keyframe_points(*map_, kf, frame, T_b_c_, cam_.pyramid, points);
  slot_races_ += added.lost_races;
  keyframe_made(std::move(kf));
}

}  // namespace orbatlas
