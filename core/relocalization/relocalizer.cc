#include "core/relocalization/relocalizer.h"

#include <cmath>
#include <unordered_set>

#include "core/common/error.h"
#include "core/map/map_point.h"
#include "core/tracking/frame_pose.h"
#include "core/tracking/projection_search.h"

namespace orbatlas {
namespace {

void clear_associations(Frame& frame) {
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  std::fill(frame.outlier.begin(), frame.outlier.end(), false);
}

// Projects the points of `keyframe` and its best covisibles that the frame has
// not matched yet, and searches around them; returns the new matches.
int guided_search(Frame& frame, const KeyFrame& keyframe, const FrameCamera& cam, const Pose3& T_b_c, float radius) {
  std::unordered_set<MapPointId> have;
  for (const auto& mp : frame.map_points)
    if (mp) have.insert(mp->id());
  const Pose3 T_c_w = (frame.T_w_b * T_b_c).inverse();
  std::vector<ProjectedPoint> candidates;
  auto add_points = [&](const KeyFrame& kf) {
    for (const auto& mp : kf.map_points()) {
      if (mp->is_bad() || !have.insert(mp->id()).second) continue;
      ProjectedPoint pp;
      if (!project_into_frame(*mp, T_c_w, cam, &pp)) continue;
      pp.point = mp;
      candidates.push_back(std::move(pp));
    }
  };
  add_points(keyframe);
  for (const auto& kf : keyframe.best_covisibles(10)) add_points(*kf);
  // search_projected_points widens th by 2.5 (head-on) to 4 (oblique) x scale;
  // th = radius / 4 keeps the window within `radius` pixels at level 0.
  return search_projected_points(frame, candidates, cam, radius / 4.0f, 0.9f);
}

// Pose from the frame's current associations: PnP-RANSAC on bearings, pose-only
// optimisation, and a guided search in the keyframe's neighbourhood when too
// few inliers remain. Returns the inliers (0 when RANSAC failed).
int solve_pose(Frame& frame, const KeyFrame& kf, const FrameCamera& cam, const Pose3& T_b_c,
               const RelocalizationOptions& options) {
  std::vector<Eigen::Vector3d> bearings, points;
  std::vector<std::size_t> keypoint_of;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const auto& mp = frame.map_points[i];
    if (!mp || mp->is_bad()) continue;
    bearings.push_back(frame.features.keypoints[i].bearing);
    points.push_back(mp->p_w());
    keypoint_of.push_back(i);
  }
  const PnpRansacResult pnp = solve_pnp_ransac(bearings, points, options.pnp);
  if (!pnp.success) return 0;
  for (std::size_t c = 0; c < keypoint_of.size(); ++c)
    if (!pnp.inliers[c]) frame.map_points[keypoint_of[c]] = nullptr;
  frame.T_w_b = pnp.T_c_w.inverse() * T_b_c.inverse();

  optimize_frame_pose(frame, cam, T_b_c);
  int good = discard_outliers(frame);
  if (good < 10) return good;
  if (good < options.min_inliers) {
    guided_search(frame, kf, cam, T_b_c, options.guided_radius);
    optimize_frame_pose(frame, cam, T_b_c);
    good = discard_outliers(frame);
  }
  return good;
}

}  // namespace

void RelocalizationOptions::check() const {
  ORBATLAS_CHECK(min_bow_matches >= 0, "relocalisation: min_bow_matches must be >= 0, not " << min_bow_matches);
  ORBATLAS_CHECK(bow_ratio >= 0.0f && bow_ratio <= 1.0f,
                 "relocalisation: bow_ratio must be in [0, 1], not " << bow_ratio);
  ORBATLAS_CHECK(min_inliers >= 0, "relocalisation: min_inliers must be >= 0, not " << min_inliers);
  ORBATLAS_CHECK(std::isfinite(guided_radius) && guided_radius >= 0.0f,
                 "relocalisation: guided_radius must be a finite value >= 0, not " << guided_radius);
  pnp.check();
}

RelocalizationResult relocalize(Frame& frame, const Vocabulary& vocabulary, const KeyframeIndex& index,
                                const FrameCamera& cam, const Pose3& T_b_c, const RelocalizationOptions& options) {
  options.check();
  RelocalizationResult result;
  if (frame.bow.empty()) vocabulary.transform(frame.features.descriptors, &frame.bow, &frame.feature_vector);
  std::size_t windows = 0;
  for (const auto& candidate : index.query(frame.bow, options.max_candidates)) {
    const auto& kf = candidate.keyframe;
    if (options.only_map && kf->map_id() != *options.only_map) continue;
    if (options.may_enter && !options.may_enter(kf->map_id())) continue;
    ++result.candidates;
    clear_associations(frame);
    int good = 0;
    if (search_by_bow(*kf, frame, options.bow_ratio) >= options.min_bow_matches)
      good = solve_pose(frame, *kf, cam, T_b_c, options);
    if (good < options.min_inliers && windows < options.window_candidates) {
      // Seen from further away or at an angle, one keyframe shares too few
      // words with the frame: match the candidate and its best covisibles
      // together (the local window place recognition uses).
      ++windows;
      clear_associations(frame);
      int matched = search_by_bow(*kf, frame, options.bow_ratio);
      for (const auto& cov : kf->best_covisibles(options.window_covisibles))
        if (!cov->is_bad() && cov->map_id() == kf->map_id()) matched += search_by_bow(*cov, frame, options.bow_ratio);
      good = matched >= options.min_bow_matches ? solve_pose(frame, *kf, cam, T_b_c, options) : 0;
      ++result.windows;
    }
    if (good < options.min_inliers) continue;
    result.success = true;
    result.keyframe = kf;
    result.map = kf->map_id();
    result.T_w_b = frame.T_w_b;
    result.inliers = good;
    frame.has_pose = true;
    return result;
  }
  clear_associations(frame);
  return result;
}

}  // namespace orbatlas
