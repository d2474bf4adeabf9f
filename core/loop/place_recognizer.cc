#include "core/loop/place_recognizer.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "core/common/error.h"
#include "core/loop/probe_frame.h"
#include "core/tracking/projection_search.h"

namespace orbatlas {
namespace {

std::unordered_set<KeyframeId> connected_ids(const KeyFrame& keyframe) {
  std::unordered_set<KeyframeId> ids{keyframe.id()};
  for (const auto& edge : keyframe.connections()) ids.insert(edge.keyframe);
  return ids;
}

// The keyframe's own 3D point for a slot, in its camera frame: its map point if
// it has one, else the stereo depth of the keypoint.
std::optional<Eigen::Vector3d> own_point_c(const KeyFrame& keyframe, const Pose3& T_c_w, std::size_t slot) {
  if (const auto mp = keyframe.map_point(slot); mp && !mp->is_bad()) return T_c_w * mp->p_w();
  const float z = keyframe.depth(slot);
  if (z <= 0.0f) return std::nullopt;
  const Eigen::Vector3d& bearing = keyframe.keypoint(slot).bearing;
  return bearing * (static_cast<double>(z) / bearing.z());
}

}  // namespace

std::optional<Sim3Match> PlaceRecognizer::make_match(const KeyFrame& keyframe, const Pose3& T_a_w, std::size_t slot,
                                                     const KeyFrame& matched, const Pose3& T_m_w,
                                                     const MapPoint& point) const {
  const auto p_a = own_point_c(keyframe, T_a_w, slot);
  if (!p_a) return std::nullopt;
  const Keypoint& ka = keyframe.keypoint(slot);
  const Eigen::Vector3d p_m = T_m_w * point.p_w();
  Eigen::Vector2d uv_m;
  double sigma2_m = cam_.pyramid.sigma2(ka.level);
  if (const auto slot_m = point.slot_in(matched.id())) {
    const Keypoint& km = matched.keypoint(*slot_m);
    uv_m = km.uv.cast<double>();
    sigma2_m = cam_.pyramid.sigma2(km.level);
  } else if (!(p_m.z() > 0.0) || !cam_.camera->project(p_m, &uv_m)) {
    return std::nullopt;
  }
  return Sim3Match{*p_a, p_m, ka.uv.cast<double>(), uv_m, cam_.pyramid.sigma2(ka.level), sigma2_m};
}

void PlaceRecognitionOptions::check() const {
  ORBATLAS_CHECK(scope == PlaceScope::kSameMap || scope == PlaceScope::kOtherMaps,
                 "place recognition: scope must be kSameMap or kOtherMaps, not " << static_cast<int>(scope));
  ORBATLAS_CHECK(bow_ratio >= 0.0f && bow_ratio <= 1.0f,
                 "place recognition: bow_ratio must be in [0, 1], not " << bow_ratio);
  ORBATLAS_CHECK(min_bow_matches >= 0, "place recognition: min_bow_matches must be >= 0, not " << min_bow_matches);
  ORBATLAS_CHECK(min_ransac_inliers >= 0,
                 "place recognition: min_ransac_inliers must be >= 0, not " << min_ransac_inliers);
  ORBATLAS_CHECK(std::isfinite(first_search_th) && first_search_th >= 0.0f,
                 "place recognition: first_search_th must be a finite value >= 0, not " << first_search_th);
  ORBATLAS_CHECK(min_projection_matches >= 0,
                 "place recognition: min_projection_matches must be >= 0, not " << min_projection_matches);
  ORBATLAS_CHECK(min_refined_inliers >= 0,
                 "place recognition: min_refined_inliers must be >= 0, not " << min_refined_inliers);
  ORBATLAS_CHECK(std::isfinite(second_search_th) && second_search_th >= 0.0f,
                 "place recognition: second_search_th must be a finite value >= 0, not " << second_search_th);
  ORBATLAS_CHECK(min_final_matches >= 0,
                 "place recognition: min_final_matches must be >= 0, not " << min_final_matches);
  ORBATLAS_CHECK(verify_matches >= 0, "place recognition: verify_matches must be >= 0, not " << verify_matches);
  ORBATLAS_CHECK(verify_keyframes >= 0, "place recognition: verify_keyframes must be >= 0, not " << verify_keyframes);
  ORBATLAS_CHECK(max_consecutive_failures >= 0,
                 "place recognition: max_consecutive_failures must be >= 0, not " << max_consecutive_failures);
}

PlaceRecognizer::PlaceRecognizer(const KeyframeIndex& index, FrameCamera cam, PlaceRecognitionOptions options)
    : index_(index), cam_(std::move(cam)), options_((options.check(), std::move(options))) {
  ORBATLAS_CHECK(cam_.camera != nullptr, "place recognition needs a camera");
}

PlaceRecognitionStep PlaceRecognizer::process(const std::shared_ptr<KeyFrame>& keyframe, bool free_scale) {
  PlaceRecognitionStep step;
  if (!keyframe || keyframe->is_bad()) return step;

  if (pending_) {
    // Verification carried over to a new keyframe, without the bag of words.
    PlaceMatch& m = pending_->match;
    const bool usable = m.current && !m.current->is_bad() && m.matched && !m.matched->is_bad() &&
                        keyframe->map_id() == m.current->map_id();
    if (usable) {
      const Pose3 T_new_old = keyframe->T_w_c().inverse() * m.current->T_w_c();
      const Sim3 S_c_w = Sim3(T_new_old) * m.S_c_w_corrected;
      const int n = confirm(*keyframe, rigid_pose_c_w(S_c_w), m);
      step.best_matches = n;
      if (n >= options_.verify_matches) {
        ++m.verified_keyframes;
        m.current = keyframe;
        m.S_c_w_corrected = S_c_w;
        m.S_cur_m = S_c_w * Sim3(m.matched->T_w_c());
        m.matches = n;
        pending_->failures = 0;
        if (m.verified_keyframes >= options_.verify_keyframes) {
          step.match = std::move(m);
          pending_.reset();
          return step;
        }
      } else if (++pending_->failures >= options_.max_consecutive_failures) {
        pending_.reset();
      }
      step.pending = pending_.has_value();
      if (pending_) return step;
    } else {
      pending_.reset();
    }
  }

  std::optional<PlaceMatch> m = detect(keyframe, free_scale, step);
  if (!m) return step;
  step.hypothesis = true;
  verify_with_covisibles(*m);
  if (m->verified_keyframes >= options_.verify_keyframes) {
    step.match = std::move(m);
  } else {
    pending_ = Hypothesis{std::move(*m), 0};
    step.pending = true;
  }
  return step;
}

std::optional<PlaceMatch> PlaceRecognizer::detect(const std::shared_ptr<KeyFrame>& keyframe, bool free_scale,
                                                  PlaceRecognitionStep& step) {
  if (keyframe->bow().empty()) return std::nullopt;
  const auto exclude = connected_ids(*keyframe);
  const MapId own = keyframe->map_id();
  const KeyframeIndex::Filter in_scope = [&](const KeyFrame& kf) {
    if (options_.scope == PlaceScope::kSameMap) return kf.map_id() == own;
    return kf.map_id() != own && (!options_.may_use_map || options_.may_use_map(kf.map_id()));
  };
  const auto results = index_.query(keyframe->bow(), options_.index_results, exclude, in_scope);

  // Score each result with its covisibility group (ORB-SLAM's accumulated
  // score) and keep each group's best keyframe.
  std::unordered_map<KeyframeId, double> score;
  for (const auto& r : results) score[r.keyframe->id()] = r.score;
  struct Group {
    std::shared_ptr<KeyFrame> best;
    double accumulated = 0.0;
  };
  std::vector<Group> groups;
  for (const auto& r : results) {
    Group g{r.keyframe, r.score};
    double best_score = r.score;
    for (const auto& neighbour : r.keyframe->best_covisibles(10)) {
      const auto it = score.find(neighbour->id());
      if (it == score.end()) continue;
      g.accumulated += it->second;
      if (it->second > best_score) {
        best_score = it->second;
        g.best = neighbour;
      }
    }
    groups.push_back(std::move(g));
  }
  std::sort(groups.begin(), groups.end(), [](const Group& a, const Group& b) {
    return a.accumulated != b.accumulated ? a.accumulated > b.accumulated : a.best->id() < b.best->id();
  });
  std::vector<std::shared_ptr<KeyFrame>> candidates;
  std::unordered_set<KeyframeId> taken;
  for (const auto& g : groups) {
    if (candidates.size() >= options_.candidates) break;
    if (taken.insert(g.best->id()).second) candidates.push_back(g.best);
  }
  step.bow_candidates = !candidates.empty();

  std::optional<PlaceMatch> best;
  for (const auto& candidate : candidates) {
    auto m = try_candidate(keyframe, candidate, exclude, free_scale);
    if (m && (!best || m->matches > best->matches)) best = std::move(m);
  }
  if (best) step.best_matches = best->matches;
  return best;
}

std::optional<PlaceMatch> PlaceRecognizer::try_candidate(const std::shared_ptr<KeyFrame>& keyframe,
                                                         const std::shared_ptr<KeyFrame>& candidate,
                                                         const std::unordered_set<KeyframeId>& connected,
                                                         bool free_scale) {
  std::vector<std::shared_ptr<KeyFrame>> window{candidate};
  for (auto& kf : candidate->best_covisibles(options_.window_covisibles))
    if (kf->map_id() == candidate->map_id() && !connected.count(kf->id())) window.push_back(std::move(kf));

  // 1. Bag-of-words matches with every window keyframe; the one with most is K_m.
  Frame probe = probe_frame(*keyframe);
  std::shared_ptr<KeyFrame> matched;
  int most = 0;
  for (const auto& w : window) {
    if (w->is_bad()) continue;
    const int n = search_by_bow(*w, probe, options_.bow_ratio);
    if (n > most) {
      most = n;
      matched = w;
    }
  }
  if (!matched || associated_count(probe) < options_.min_bow_matches) return std::nullopt;

  const Pose3 T_a_w = keyframe->T_w_c().inverse();
  const Pose3 T_m_w = matched->T_w_c().inverse();
  const Camera& camera = *cam_.camera;

  // 2. Horn 3-point RANSAC (both reprojections scored; where K_m does not observe
  // the window point, its image term compares with where K_m would see it).
  std::vector<Sim3Match> ransac_matches;
  std::unordered_set<MapPointId> used;
  for (std::size_t i = 0; i < probe.size(); ++i) {
    const auto& mp = probe.map_points[i];
    if (!mp || mp->is_bad() || !used.insert(mp->id()).second) continue;
    if (auto match = make_match(*keyframe, T_a_w, i, *matched, T_m_w, *mp)) ransac_matches.push_back(*match);
  }
  if (static_cast<int>(ransac_matches.size()) < options_.min_ransac_inliers) return std::nullopt;
  Sim3SolverOptions so;
  so.fix_scale = !free_scale;
  so.min_inliers = options_.min_ransac_inliers;
  so.seed = options_.seed + attempts_++;
  const Sim3SolverResult ransac = solve_sim3_ransac(std::move(ransac_matches), camera, camera, so);
  if (!ransac.success) return std::nullopt;
  Sim3 S_a_m = ransac.S_1_2;

  // 3. Guided matching with every window point, refinement, then a narrower pass.
  std::vector<std::shared_ptr<MapPoint>> window_points;
  std::unordered_set<MapPointId> seen;
  for (const auto& w : window)
    for (auto& mp : w->map_points())
      if (!mp->is_bad() && seen.insert(mp->id()).second) window_points.push_back(std::move(mp));

  PlaceMatch m;
  m.window = window;
  m.window_points = std::move(window_points);
  int matches = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const float th = pass == 0 ? options_.first_search_th : options_.second_search_th;
    Frame guided = probe_frame(*keyframe);
    const Pose3 T_c_w = rigid_pose_c_w(S_a_m * Sim3(T_m_w));
    std::vector<ProjectedPoint> projected;
    ProjectedPoint pp;
    for (const auto& mp : m.window_points)
      if (project_into_frame(*mp, T_c_w, cam_, &pp)) {
        pp.point = mp;
        projected.push_back(pp);
      }
    matches = search_projected_points(guided, projected, cam_, th, 0.9f);
    const int needed = pass == 0 ? options_.min_projection_matches : options_.min_final_matches;
    if (matches < needed) return std::nullopt;

    std::vector<Sim3Match> refine_matches;
    for (std::size_t i = 0; i < guided.size(); ++i) {
      const auto& mp = guided.map_points[i];
      if (!mp || mp->is_bad()) continue;
      if (auto match = make_match(*keyframe, T_a_w, i, *matched, T_m_w, *mp)) refine_matches.push_back(*match);
    }
    Sim3RefinementOptions ro;
    ro.fix_scale = !free_scale;
    const Sim3RefinementResult refined = refine_sim3(S_a_m, refine_matches, camera, camera, ro);
    if (!refined.success || refined.inlier_count < options_.min_refined_inliers) return std::nullopt;
    S_a_m = refined.S_1_2;
  }

  m.current = keyframe;
  m.detected_on = keyframe;
  m.matched = matched;
  m.S_cur_m = S_a_m;
  m.S_c_w_corrected = S_a_m * Sim3(T_m_w);
  m.scale_free = free_scale;
  m.matches = matches;
  m.verified_keyframes = 1;
  return m;
}

int PlaceRecognizer::confirm(const KeyFrame& keyframe, const Pose3& T_c_w, const PlaceMatch& match) const {
  Frame probe = probe_frame(keyframe);
  std::vector<ProjectedPoint> projected;
  ProjectedPoint pp;
  for (const auto& mp : match.window_points)
    if (!mp->is_bad() && project_into_frame(*mp, T_c_w, cam_, &pp)) {
      pp.point = mp;
      projected.push_back(pp);
    }
  return search_projected_points(probe, projected, cam_, options_.second_search_th, 0.9f);
}

void PlaceRecognizer::verify_with_covisibles(PlaceMatch& match) const {
  std::unordered_set<KeyframeId> in_window;
  for (const auto& w : match.window) in_window.insert(w->id());
  const Pose3 T_w_a = match.current->T_w_c();
  for (const auto& cov : match.current->best_covisibles(options_.verify_covisibles)) {
    if (match.verified_keyframes >= options_.verify_keyframes) break;
    if (cov->is_bad() || in_window.count(cov->id()) || cov->map_id() != match.current->map_id()) continue;
    const Pose3 T_c_w = rigid_pose_c_w(Sim3(cov->T_w_c().inverse() * T_w_a) * match.S_c_w_corrected);
    if (confirm(*cov, T_c_w, match) >= options_.verify_matches) ++match.verified_keyframes;
  }
}

}  // namespace orbatlas
