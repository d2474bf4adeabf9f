#include "core/mapping/fusion.h"

#include "core/features/descriptor.h"
#include "core/map/map_point_update.h"
#include "core/optimization/chi2.h"

namespace orbatlas {

FusionStats fuse_into_keyframe(Map& map, const std::shared_ptr<KeyFrame>& keyframe,
                               const std::vector<std::shared_ptr<MapPoint>>& points, const FrameCamera& cam, float th) {
  FusionStats stats;
  const Pose3 T_w_c = keyframe->T_w_c();
  const Pose3 T_c_w = T_w_c.inverse();
  const auto& features = keyframe->features();
  std::vector<std::size_t> candidates;
  for (const auto& mp : points) {
    if (!mp || mp->is_bad() || keyframe->is_bad()) continue;
    if (mp->slot_in(keyframe->id())) continue;
    const Eigen::Vector3d p_w = mp->p_w();
    const Eigen::Vector3d p_c = T_c_w * p_w;
    if (p_c.z() <= 0.0) continue;
    Eigen::Vector2d uv;
    if (!cam.camera->project(p_c, &uv) || !cam.camera->in_image(uv)) continue;
    const Eigen::Vector3d ray = p_w - T_w_c.t;
    const double distance = ray.norm();
    if (distance < 0.8 * mp->min_distance() || distance > 1.2 * mp->max_distance()) continue;
    const Eigen::Vector3d normal = mp->normal();
    if (normal.squaredNorm() > 0.0 && ray.dot(normal) < 0.5 * distance) continue;
    const int level = cam.pyramid.predict_level(distance, mp->max_distance());
    const float radius = th * static_cast<float>(cam.pyramid.scale(level));
    keyframe->grid().in_radius(uv.cast<float>(), radius, level - 1, level, candidates);
    if (candidates.empty()) continue;
    const double ur = cam.bf > 0.0 ? uv.x() - cam.bf / p_c.z() : -1.0;
    const Descriptor d = mp->descriptor();
    int best = 256;
    std::size_t best_slot = 0;
    for (const std::size_t i : candidates) {
      const Keypoint& kp = features.keypoints[i];
      const double inv_sigma2 = 1.0 / cam.pyramid.sigma2(kp.level);
      double e2 = (uv - kp.uv.cast<double>()).squaredNorm();
      const float kp_ur = keyframe->u_right(i);
      if (kp_ur >= 0.0f && ur >= 0.0) {
        const double er = ur - kp_ur;
        if ((e2 + er * er) * inv_sigma2 > kChi2Stereo95) continue;
      } else if (e2 * inv_sigma2 > kChi2Mono95) {
        continue;
      }
      const int dist = hamming(d, features.descriptors[i]);
      if (dist < best) {
        best = dist;
        best_slot = i;
      }
    }
    if (best > kHammingLow) continue;
    const auto existing = keyframe->map_point(best_slot);
    if (existing && !existing->is_bad()) {
      if (existing == mp) continue;
      const bool keep_existing = existing->observation_count() > mp->observation_count();
      if (keep_existing ? replace_map_point(map, mp, existing) : replace_map_point(map, existing, mp)) ++stats.merged;
    } else if (add_observation_if_free(*keyframe, best_slot, mp)) {
      ++stats.added;
    }
  }
  return stats;
}

}  // namespace orbatlas
