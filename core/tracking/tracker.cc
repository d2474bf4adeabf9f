#include "core/tracking/tracker.h"

#include <algorithm>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "core/common/error.h"
#include "core/map/map_point_update.h"
#include "core/tracking/frame_pose.h"

namespace orbatlas {
namespace {

constexpr float kMotionModelRadius = 7.0f;       // ORB-SLAM's th for stereo
constexpr float kMonoMotionModelRadius = 15.0f;  // and for a single camera
constexpr int kMinMotionMatches = 20;
constexpr int kMinPoseInliers = 10;
constexpr int kMinBowMatches = 15;

double seconds_between(TimestampNs a, TimestampNs b) { return static_cast<double>(b - a) * 1e-9; }

int count_inliers(const Frame& frame) {
  int inliers = 0;
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (frame.map_points[i] && !frame.outlier[i]) ++inliers;
  return inliers;
}

}  // namespace

void TrackerOptions::check() const {
  ORBATLAS_CHECK(min_init_stereo_points > 0,
                 "tracker: min_init_stereo_points must be > 0, not " << min_init_stereo_points);
  ORBATLAS_CHECK(th_depth_m >= 0.0, "tracker: th_depth_m must be >= 0, not " << th_depth_m);
  ORBATLAS_CHECK(max_frames_between_keyframes >= 1,
                 "tracker: max_frames_between_keyframes must be >= 1, not " << max_frames_between_keyframes);
  ORBATLAS_CHECK(std::isfinite(max_keyframe_interval_s) && max_keyframe_interval_s >= 0.0,
                 "tracker: max_keyframe_interval_s must be >= 0, not " << max_keyframe_interval_s);
  ORBATLAS_CHECK(min_inliers >= 0, "tracker: min_inliers must be >= 0, not " << min_inliers);
  ORBATLAS_CHECK(min_inliers_after_recovery >= 0,
                 "tracker: min_inliers_after_recovery must be >= 0, not " << min_inliers_after_recovery);
  ORBATLAS_CHECK(min_inliers_inertial >= 0 && min_inliers_inertial_recently_lost >= 0,
                 "tracker: min_inliers_inertial and min_inliers_inertial_recently_lost must be >= 0");
  ORBATLAS_CHECK(recently_lost_s >= 0.0, "tracker: recently_lost_s must be >= 0, not " << recently_lost_s);
  ORBATLAS_CHECK(
      new_map_after_failed_relocalizations >= 0,
      "tracker: new_map_after_failed_relocalizations must be >= 0, not " << new_map_after_failed_relocalizations);
  ORBATLAS_CHECK(
      std::isfinite(max_mapping_wait_ms) && max_mapping_wait_ms >= 0.0 && max_mapping_wait_ms <= kLongestMappingWaitMs,
      "tracker: max_mapping_wait_ms must be in [0, " << kLongestMappingWaitMs << "], not " << max_mapping_wait_ms);
  ORBATLAS_CHECK(max_local_keyframes >= 0, "tracker: max_local_keyframes must be >= 0, not " << max_local_keyframes);
  ORBATLAS_CHECK(min_keyframes_to_keep_map >= 0,
                 "tracker: min_keyframes_to_keep_map must be >= 0, not " << min_keyframes_to_keep_map);
  monocular.check();
}

const char* tracking_state_name(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialized:
      return "NOT_INITIALIZED";
    case TrackingState::kOk:
      return "OK";
    case TrackingState::kRecentlyLost:
      return "RECENTLY_LOST";
    case TrackingState::kLost:
      return "LOST";
  }
  return "?";
}

Tracker::Tracker(Atlas& atlas, const Vocabulary& vocabulary, KeyframeSink& sink, FrameCamera cam, Pose3 T_b_c,
                 TrackerOptions options, FrameRelocalizer* relocalizer)
    : atlas_(atlas),
      vocabulary_(vocabulary),
      sink_(sink),
      relocalizer_(relocalizer),
      cam_(std::move(cam)),
      T_b_c_(T_b_c),
      options_(options),
      monocular_(cam_.bf <= 0.0) {
  options_.check();
  ORBATLAS_CHECK(cam_.camera != nullptr, "tracker needs a camera");
  ORBATLAS_CHECK(!options_.localization_only || relocalizer_ != nullptr,
                 "localisation on stored maps needs a relocaliser");
  if (monocular_ && !options_.localization_only)
    mono_initializer_ = std::make_unique<MonocularInitializer>(options_.monocular, cam_.camera->calibration().fx);
}

TrackResult Tracker::track(Frame frame) {
  accept_frame(frame);
  imu_prediction_.reset();
  TrackResult result;
  result.t_ns = frame.t_ns;
  local_points_ = 0;

  follow_merged_map();
  adopt_reference_units();
  const bool joined_stored_map = !options_.localization_only && !map_ && options_.start_in_stored_map && relocalizer_ &&
                                 join_stored_map(frame, result);
  bool ok = joined_stored_map;
  if (!options_.localization_only && (state_ == TrackingState::kLost || !map_)) start_new_map();

  if (joined_stored_map) {
    // tracked above
  } else if (options_.localization_only && state_ != TrackingState::kOk && state_ != TrackingState::kRecentlyLost) {
    ok = localize_in_stored_maps(frame, result);
  } else if (state_ == TrackingState::kNotInitialized) {
    ok = initialize(frame);
    if (ok) {
      result.keyframe = true;
      result.keyframe_id = reference_->id();
    }
  } else {
    ok = track_from_last_frame(frame);
    const bool by_imu = !ok && inertial_ && imu_prediction_ && inertial_->may_bridge(frame.t_ns);
    if (by_imu) failed_relocalizations_ = 0;  // the IMU carries the frame: not a failed relocalisation
    update_state(frame, ok);
    if (ok) {
      after_tracked(frame, result);
    } else {
      velocity_.reset();
    }
    if (by_imu) {
      frame.T_w_b = *imu_prediction_;
      frame.has_pose = true;
      std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
      result.by_imu = true;
    }
  }
  if (inertial_) {
    using Outcome = InertialTracking::Outcome;
    const Outcome outcome = ok ? Outcome::kVisual : result.by_imu ? Outcome::kImuOnly : Outcome::kLost;
    inertial_->frame_done(frame, last_ ? &*last_ : nullptr, outcome);
  }
  finish_frame(std::move(frame), ok || result.by_imu, result);
  return result;
}

void Tracker::accept_frame(const Frame& frame) {
  ORBATLAS_DATA_CHECK(!has_last_t_ || frame.t_ns > last_t_ns_,
                      "frame timestamps must increase: " << frame.t_ns << " ns after " << last_t_ns_ << " ns");
  ORBATLAS_CHECK(frame.map_points.size() == frame.size() && frame.outlier.size() == frame.size() &&
                     frame.depth.size() == frame.size() && frame.u_right.size() == frame.size(),
                 "frame at " << frame.t_ns << " ns has inconsistent per-keypoint arrays");
  has_last_t_ = true;
  last_t_ns_ = frame.t_ns;
  ++frame_index_;
}

bool Tracker::join_stored_map(Frame& frame, TrackResult& result) {
  // The session's first frame: is this a place a stored map knows?
  if (recover(frame) && track_local_map(frame)) {
    state_ = TrackingState::kOk;
    last_recovery_index_ = frame_index_;
    velocity_.reset();
    result.inliers = count_inliers(frame);
    return true;
  }
  map_.reset();  // not recognised (or not confirmed): a map of its own follows
  reference_.reset();
  last_keyframe_.reset();
  local_keyframes_.clear();
  return false;
}

bool Tracker::localize_in_stored_maps(Frame& frame, TrackResult& result) {
  // Not localised yet, or lost for good: look for the place in every stored map.
  bool ok = recover(frame);
  if (ok) {
    last_recovery_index_ = frame_index_;
    ok = track_local_map(frame);
  }
  if (ok) {
    state_ = TrackingState::kOk;
    result.inliers = count_inliers(frame);
  }
  velocity_.reset();
  return ok;
}

bool Tracker::track_from_last_frame(Frame& frame) {
  refresh_last_frame_pose();
  if (inertial_ && last_) {
    // This session's biases: its newest keyframe's in this map (a map other
    // sessions share holds the estimate of whichever IMU mapped last).
    std::optional<ImuBias> own_bias;
    if (last_keyframe_ && !last_keyframe_->is_bad() && last_keyframe_->map_id() == map_->id())
      if (const auto imu = last_keyframe_->imu_state()) own_bias = imu->bias;
    imu_prediction_ = inertial_->predict(*map_, *last_, frame.t_ns, own_bias);
  }
  bool ok = false;
  if (state_ == TrackingState::kOk) {
    ok = (imu_prediction_ || velocity_) && track_motion_model(frame);
    if (!ok) ok = reference_ && track_reference_keyframe(frame, reference_);
    // The IMU knows where the frame is even when the last frame's points are
    // not found again (ORB-SLAM3 goes on to the local map the same way).
    if (!ok && imu_prediction_) return track_from_imu_prediction(frame);
  } else {  // kRecentlyLost
    // Found again from the IMU's prediction: not a relocalisation (whose
    // first frames need more points), the IMU vouches for the pose.
    if (imu_prediction_ && track_from_imu_prediction(frame)) {
      failed_relocalizations_ = 0;
      return true;
    }
    // A relocalisation the local map does not confirm changes nothing: the
    // frame may still be placed by the IMU, in the map and relative to the
    // keyframe its prediction was made in (not a candidate of another map).
    std::shared_ptr<Map> map = map_;
    std::shared_ptr<KeyFrame> reference = reference_, last_keyframe = last_keyframe_;
    std::vector<std::shared_ptr<KeyFrame>> local_keyframes = local_keyframes_;
    ok = recover(frame);
    if (ok) last_recovery_index_ = frame_index_;
    failed_relocalizations_ = ok ? 0 : failed_relocalizations_ + 1;
    if (ok && track_local_map(frame)) return true;
    if (ok && map && map != map_ && !options_.localization_only && atlas_.map(map->id())) atlas_.set_active(map->id());
    map_ = std::move(map);
    reference_ = std::move(reference);
    last_keyframe_ = std::move(last_keyframe);
    local_keyframes_ = std::move(local_keyframes);
    return false;
  }
  return ok && track_local_map(frame);
}

void Tracker::update_state(const Frame& frame, bool ok) {
  const bool localizing = options_.localization_only;
  if (ok) {
    state_ = TrackingState::kOk;
  } else if (state_ == TrackingState::kOk) {
    // A small map is given up at once, unless relocalisation gets a few
    // frames before a new map starts anyway (then an older map may be found).
    const bool keep = localizing || options_.new_map_after_failed_relocalizations > 0 ||
                      map_->keyframe_count() > static_cast<std::size_t>(options_.min_keyframes_to_keep_map);
    state_ = keep ? TrackingState::kRecentlyLost : TrackingState::kLost;
    lost_since_ns_ = frame.t_ns;
    failed_relocalizations_ = 0;
  } else if (seconds_between(lost_since_ns_, frame.t_ns) > options_.recently_lost_s ||
             (!localizing && options_.new_map_after_failed_relocalizations > 0 &&
              failed_relocalizations_ >= options_.new_map_after_failed_relocalizations)) {
    state_ = TrackingState::kLost;
  }
}

void Tracker::after_tracked(Frame& frame, TrackResult& result) {
  const int inliers = count_inliers(frame);
  result.inliers = inliers;
  if (last_ && last_->has_pose) velocity_ = last_->T_w_b.inverse() * frame.T_w_b;
  if (need_new_keyframe(frame, inliers)) {
    create_keyframe(frame, false);
    result.keyframe = true;
    result.keyframe_id = reference_->id();
  }
}

void Tracker::finish_frame(Frame frame, bool ok, TrackResult& result) {
  result.state = state_;
  result.map = map_ ? map_->id() : 0;
  if (local_points_ > 0) {
    result.local_keyframes = static_cast<int>(local_keyframes_.size());
    result.local_points = local_points_;
  }
  result.tracked = ok;
  if (ok) {
    result.T_w_b = frame.T_w_b;
    frame.has_pose = true;
    // Outliers are dropped so the next frame's motion-model search uses only inliers.
    discard_outliers(frame);
    T_ref_last_ = reference_->T_w_b().inverse() * frame.T_w_b;
    last_reference_ = reference_->id();
    reference_units_ = reference_->units();
    Pose3 T_ref_b = T_ref_last_;
    T_ref_b.t /= reference_units_;  // FrameAnchor: in the keyframe's units
    last_anchor_ = FrameAnchor{frame.t_ns, map_->id(), reference_->id(), T_ref_b};
  } else {
    frame.has_pose = false;
    last_reference_.reset();
  }
  last_ = std::move(frame);
}

void Tracker::release_frames() {
  last_.reset();
  reference_.reset();
  last_keyframe_.reset();
  local_keyframes_.clear();
}

void Tracker::start_new_map() {
  if (inertial_) inertial_->reset();
  if (mono_initializer_) mono_initializer_->reset();
  if (!map_ || map_->keyframe_count() > 0) {
    map_ = atlas_.create_map();
    ++maps_started_;
  }
  state_ = TrackingState::kNotInitialized;
  velocity_.reset();
  reference_.reset();
  last_keyframe_.reset();
  local_keyframes_.clear();
  last_reference_.reset();
}

void Tracker::follow_merged_map() {
  if (!map_ || atlas_.map(map_->id())) return;  // still in the atlas
  // Merged away: the keyframes went with it, so the reference says where to.
  std::shared_ptr<Map> into = reference_ ? atlas_.map(reference_->map_id()) : nullptr;
  if (!into) {
    map_.reset();  // nothing to follow (a map without keyframes is never merged)
    if (options_.localization_only) {
      // Localised again from scratch at this frame; a localisation makes no map.
      state_ = TrackingState::kLost;
      reference_.reset();
      last_keyframe_.reset();
      local_keyframes_.clear();
      last_reference_.reset();
      velocity_.reset();
    } else {
      start_new_map();  // a map of its own
    }
    return;
  }
  map_ = std::move(into);
  if (!options_.localization_only) atlas_.set_active(map_->id());
  ++maps_followed_;
}

void Tracker::adopt_reference_units() {
  if (!map_ || !last_reference_) return;
  const auto placement = map_->keyframe_placement(*last_reference_);
  if (!placement || placement->units == reference_units_) return;
  const double f = placement->units / reference_units_;
  reference_units_ = placement->units;
  T_ref_last_.t *= f;
  if (velocity_) velocity_->t *= f;
  if (inertial_) inertial_->rescale(f);
}

void Tracker::refresh_last_frame_pose() {
  // The last frame's pose relative to its reference keyframe, which local BA may have moved.
  if (!last_ || !last_->has_pose || !last_reference_) return;
  if (const auto pose = map_->keyframe_pose(*last_reference_)) last_->T_w_b = *pose * T_ref_last_;
}

void Tracker::ensure_bow(Frame& frame) const {
  if (frame.bow.empty()) vocabulary_.transform(frame.features.descriptors, &frame.bow, &frame.feature_vector);
}

bool Tracker::initialize(Frame& frame) {
  // A new map waits (a frame or two) while local mapping cannot take its first
  // keyframe: the insert below blocks on a full queue, under the tracking lock a
  // paused mapper's loop correction is waiting for (docs/architecture.md, Locks).
  if (!options_.localization_only && (!sink_.accepting(map_->id()) || sink_.queued(map_->id()) >= 3)) return false;
  if (monocular_) return initialize_monocular(frame);
  if (static_cast<int>(frame.stereo_count()) < options_.min_init_stereo_points) return false;
  frame.T_w_b = Pose3();
  // With an IMU the map starts level (its gravity measured at this frame).
  if (const auto level = inertial_ ? inertial_->level_rotation(frame.t_ns) : std::nullopt) frame.T_w_b.q = *level;
  frame.has_pose = true;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  create_keyframe(frame, true);
  local_keyframes_ = {reference_};
  state_ = TrackingState::kOk;
  velocity_.reset();
  return true;
}

bool Tracker::track_motion_model(Frame& frame) {
  if (!last_ || !last_->has_pose) return false;
  frame.T_w_b = imu_prediction_ ? *imu_prediction_ : last_->T_w_b * *velocity_;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  const Pose3 T_c_w = (frame.T_w_b * T_b_c_).inverse();
  const float radius = monocular_ ? kMonoMotionModelRadius : kMotionModelRadius;
  int matches = search_from_last_frame(frame, *last_, T_c_w, cam_, radius);
  if (matches < kMinMotionMatches) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    matches = search_from_last_frame(frame, *last_, T_c_w, cam_, 2.0f * radius);
  }
  if (matches < kMinMotionMatches) return false;
  optimize_frame_pose(frame, cam_, T_b_c_);
  return discard_outliers(frame) >= kMinPoseInliers;
}

bool Tracker::track_reference_keyframe(Frame& frame, const std::shared_ptr<KeyFrame>& keyframe) {
  if (!keyframe || keyframe->is_bad()) return false;
  ensure_bow(frame);
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  if (search_by_bow(*keyframe, frame) < kMinBowMatches) return false;
  frame.T_w_b = imu_prediction_ ? *imu_prediction_ : (last_ && last_->has_pose) ? last_->T_w_b : keyframe->T_w_b();
  optimize_frame_pose(frame, cam_, T_b_c_);
  return discard_outliers(frame) >= kMinPoseInliers;
}

bool Tracker::track_from_imu_prediction(Frame& frame) {
  frame.T_w_b = *imu_prediction_;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  return track_local_map(frame);
}

bool Tracker::recover(Frame& frame) {
  if (relocalizer_) {
    // Against every map of the atlas; tracking resumes in the map recognised.
    ensure_bow(frame);
    const auto found = relocalizer_->relocalize(frame);
    if (!found) return false;
    if (!map_ || found->map != map_->id()) {
      auto map = atlas_.map(found->map);
      if (!map) return false;
      map_ = std::move(map);
      if (!options_.localization_only) atlas_.set_active(found->map);  // a localisation changes nothing
      last_keyframe_.reset();
    }
    reference_ = found->keyframe;
    ++relocalizations_;
    return true;
  }
  // Without a relocaliser: the last reference keyframe and its best covisibles.
  std::vector<std::shared_ptr<KeyFrame>> candidates;
  if (reference_ && !reference_->is_bad()) {
    candidates.push_back(reference_);
    for (auto& kf : reference_->best_covisibles(5)) candidates.push_back(std::move(kf));
  }
  for (const auto& kf : candidates) {
    if (track_reference_keyframe(frame, kf)) {
      reference_ = kf;
      return true;
    }
  }
  return false;
}

}  // namespace orbatlas
