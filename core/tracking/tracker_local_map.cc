// Tracker: the frame's local map (the keyframes that see its points and their
// neighbours, the points they hold) and the pose optimised against it.
#include <algorithm>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "core/common/error.h"
#include "core/map/map_point_update.h"
#include "core/tracking/frame_pose.h"
#include "core/tracking/tracker.h"

namespace orbatlas {

void Tracker::update_local_map(const Frame& frame) {
  // Keyframes that observe the frame's points, by how many; the best is the new reference.
  // (Weak links under the points' locks, made strong after: docs/map_model.md.)
  std::unordered_map<KeyframeId, std::pair<std::weak_ptr<KeyFrame>, int>> counts;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp || mp->is_bad()) continue;
    mp->for_each_observer([&](KeyframeId id, const std::weak_ptr<KeyFrame>& kf) {
      auto& entry = counts[id];
      if (entry.second++ == 0) entry.first = kf;
    });
  }
  // No association (a frame placed by the IMU's prediction alone): the last
  // local map is where to look.
  if (counts.empty()) return;
  local_keyframes_.clear();
  std::unordered_set<KeyframeId> in_local;
  std::vector<std::pair<int, std::shared_ptr<KeyFrame>>> sorted;
  for (auto& [id, entry] : counts) {
    auto kf = entry.first.lock();
    if (!kf || kf->is_bad()) continue;
    sorted.emplace_back(entry.second, std::move(kf));
  }
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second->id() < b.second->id();
  });
  // The keyframes sharing the most points first, at most max_local_keyframes
  // of them: in a map several sessions map, far more keyframes than that see
  // the same points (measured up to 110), and each brings its points to the search.
  const std::size_t max_kfs = static_cast<std::size_t>(options_.max_local_keyframes);
  const std::shared_ptr<KeyFrame> best = sorted.empty() ? nullptr : sorted.front().second;
  for (auto& entry : sorted) {
    if (local_keyframes_.size() >= max_kfs) break;
    in_local.insert(entry.second->id());
    local_keyframes_.push_back(std::move(entry.second));
  }
  const std::size_t first_ring = local_keyframes_.size();
  auto add = [&](const std::shared_ptr<KeyFrame>& kf) {
    if (kf && !kf->is_bad() && local_keyframes_.size() < max_kfs && in_local.insert(kf->id()).second)
      local_keyframes_.push_back(kf);
  };
  for (std::size_t k = 0; k < first_ring && local_keyframes_.size() < max_kfs; ++k) {
    const auto kf = local_keyframes_[k];
    for (const auto& n : kf->best_covisibles(10)) add(n);
    for (const auto& c : kf->children()) add(c);
    add(kf->parent());
  }
  if (best) reference_ = best;
}

bool Tracker::track_local_map(Frame& frame) {
  update_local_map(frame);
  // A point's visible / found counts feed point culling in the map's own
  // mapping; a localisation changes nothing in the map, these counts included.
  const bool count = !options_.localization_only;
  FlatIdSet& seen = local_points_seen_;
  seen.clear(frame.size() + 4096);
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp || mp->is_bad()) continue;
    if (count) mp->increase_visible();
    seen.insert(mp->id());
  }
  const Pose3 T_c_w = (frame.T_w_b * T_b_c_).inverse();
  std::vector<ProjectedPoint>& candidates = local_candidates_;
  candidates.clear();
  for (const auto& kf : local_keyframes_) {
    // (A culled point is marked seen and skipped: it stays culled, so no later slot of it counts.)
    kf->for_each_unseen_map_point(seen, [&](const std::shared_ptr<MapPoint>& mp) {
      if (mp->is_bad()) return;
      ProjectedPoint pp;
      if (!project_into_frame(*mp, T_c_w, cam_, &pp)) return;
      if (count) mp->increase_visible();
      pp.point = mp;
      candidates.push_back(std::move(pp));
    });
  }
  local_points_ = static_cast<int>(candidates.size());
  float th = 1.0f;
  if (frame_index_ < last_recovery_index_ + 2) th = 5.0f;
  if (state_ == TrackingState::kRecentlyLost) th = 15.0f;
  // The points stay alive through the frame's associations only, also when the search throws.
  try {
    search_projected_points(frame, candidates, cam_, th);
  } catch (...) {
    candidates.clear();
    throw;
  }
  candidates.clear();

  // With the IMU (a prediction for this frame): the visual-inertial optimisation.
  const std::optional<int> inertial = inertial_ && imu_prediction_ ? inertial_->optimize(frame, cam_) : std::nullopt;
  if (!inertial) optimize_frame_pose(frame, cam_, T_b_c_);
  int inliers = 0;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp || frame.outlier[i] || mp->is_bad()) continue;
    if (count) mp->increase_found();
    if (mp->observation_count() > 0) ++inliers;
  }
  const bool recovering = frame_index_ < last_recovery_index_ + options_.max_frames_between_keyframes;
  if (recovering) return inliers >= options_.min_inliers_after_recovery;
  if (inertial && state_ == TrackingState::kRecentlyLost) return inliers >= options_.min_inliers_inertial_recently_lost;
  return inliers >= (inertial ? options_.min_inliers_inertial : options_.min_inliers);
}

}  // namespace orbatlas
