#include "core/tracking/projection_search.h"

#include <cmath>

#include "core/features/matching.h"
#include "core/map/map_point.h"

namespace orbatlas {
namespace {

bool free_keypoint(const Frame& frame, std::size_t i) {
  const auto& mp = frame.map_points[i];
  return !mp || mp->is_bad() || mp->observation_count() == 0;
}

void apply_rotation_check(const ImageFeatures& a, const ImageFeatures& b, std::vector<FeatureMatch>& matches,
                          Frame& frame) {
  RotationHistogram histogram;
  for (std::size_t m = 0; m < matches.size(); ++m)
    histogram.add(a.keypoints[matches[m].a].angle_deg - b.keypoints[matches[m].b].angle_deg, m);
  for (const std::size_t m : histogram.outliers()) frame.map_points[matches[m].b] = nullptr;
}

}  // namespace

bool project_into_frame(const MapPoint& point, const Pose3& T_c_w, const FrameCamera& cam, ProjectedPoint* out) {
  const MapPoint::Geometry g = point.geometry();
  const Eigen::Vector3d& p_w = g.p_w;
  const Eigen::Vector3d p_c = T_c_w * p_w;
  if (p_c.z() <= 0.0) return false;
  Eigen::Vector2d uv;
  if (!cam.camera->project(p_c, &uv) || !cam.camera->in_image(uv)) return false;
  const Eigen::Vector3d center = T_c_w.inverse().t;
  const Eigen::Vector3d ray = p_w - center;
  const double distance = ray.norm();
  const double min_d = 0.8 * g.min_distance, max_d = 1.2 * g.max_distance;
  if (distance < min_d || distance > max_d) return false;
  const Eigen::Vector3d& normal = g.normal;
  const double view_cos = normal.squaredNorm() > 0.0 ? ray.dot(normal) / distance : 1.0;
  if (view_cos < 0.5) return false;
  out->uv = uv.cast<float>();
  out->u_right = cam.bf > 0.0 ? static_cast<float>(uv.x() - cam.bf / p_c.z()) : -1.0f;
  out->level = cam.pyramid.predict_level(distance, g.max_distance);
  out->view_cos = static_cast<float>(view_cos);
  return true;
}

int search_projected_points(Frame& frame, const std::vector<ProjectedPoint>& points, const FrameCamera& cam, float th,
                            float ratio) {
  int matches = 0;
  std::vector<std::size_t> candidates;
  for (const auto& pp : points) {
    if (!pp.point || pp.point->is_bad()) continue;
    const float radius = th * (pp.view_cos > 0.998f ? 2.5f : 4.0f) * static_cast<float>(cam.pyramid.scale(pp.level));
    frame.grid.in_radius(pp.uv, radius, pp.level - 1, pp.level, candidates);
    if (candidates.empty()) continue;
    const Descriptor d = pp.point->descriptor();
    int best = 256, second = 256, best_level = -1, second_level = -1;
    std::size_t best_index = 0;
    for (const std::size_t i : candidates) {
      if (!free_keypoint(frame, i)) continue;
      if (pp.u_right >= 0.0f && frame.u_right[i] > 0.0f && std::abs(pp.u_right - frame.u_right[i]) > radius) continue;
      const int dist = hamming(d, frame.features.descriptors[i]);
      const int level = frame.features.keypoints[i].level;
      if (dist < best) {
        second = best;
        second_level = best_level;
        best = dist;
        best_level = level;
        best_index = i;
      } else if (dist < second) {
        second = dist;
        second_level = level;
      }
    }
    if (best > kHammingHigh) continue;
    if (best_level == second_level && static_cast<float>(best) > ratio * static_cast<float>(second)) continue;
    frame.map_points[best_index] = pp.point;
    frame.outlier[best_index] = false;
    ++matches;
  }
  return matches;
}

int search_from_last_frame(Frame& current, const Frame& last, const Pose3& T_c_w, const FrameCamera& cam, float th) {
  std::vector<FeatureMatch> matches;
  std::vector<std::size_t> candidates;
  for (std::size_t j = 0; j < last.size(); ++j) {
    const auto& mp = last.map_points[j];
    if (!mp || mp->is_bad() || last.outlier[j]) continue;
    const Eigen::Vector3d p_c = T_c_w * mp->p_w();
    if (p_c.z() <= 0.0) continue;
    Eigen::Vector2d uv;
    if (!cam.camera->project(p_c, &uv) || !cam.camera->in_image(uv)) continue;
    const int level = last.features.keypoints[j].level;
    const float radius = th * static_cast<float>(cam.pyramid.scale(level));
    current.grid.in_radius(uv.cast<float>(), radius, std::max(0, level - 1), level + 1, candidates);
    if (candidates.empty()) continue;
    const float u_right = cam.bf > 0.0 ? static_cast<float>(uv.x() - cam.bf / p_c.z()) : -1.0f;
    const Descriptor d = mp->descriptor();
    int best = 256;
    std::size_t best_index = 0;
    for (const std::size_t i : candidates) {
      if (!free_keypoint(current, i)) continue;
      if (u_right >= 0.0f && current.u_right[i] > 0.0f && std::abs(u_right - current.u_right[i]) > radius) continue;
      const int dist = hamming(d, current.features.descriptors[i]);
      if (dist < best) {
        best = dist;
        best_index = i;
      }
    }
    if (best > kHammingHigh) continue;
    current.map_points[best_index] = mp;
    current.outlier[best_index] = false;
    matches.push_back({j, best_index, best});
  }
  apply_rotation_check(last.features, current.features, matches, current);
  int n = 0;
  for (const auto& m : matches)
    if (current.map_points[m.b]) ++n;
  return n;
}

int search_by_bow(const KeyFrame& keyframe, Frame& frame, float ratio) {
  const auto slots = keyframe.slots();
  const auto& kf_features = keyframe.features();
  std::vector<FeatureMatch> matches;
  std::vector<int> taken_distance(frame.size(), 257);
  std::vector<std::size_t> taken_by(frame.size(), BestTwo::kNone);
  for_each_common_node(keyframe.feature_vector(), frame.feature_vector,
                       [&](const auto& kf_slots, const auto& frame_kps) {
                         for (const std::uint32_t k : kf_slots) {
                           const auto& mp = slots[k];
                           if (!mp || mp->is_bad()) continue;
                           const Descriptor& d = kf_features.descriptors[k];
                           BestTwo best;
                           for (const std::uint32_t i : frame_kps) {
                             if (frame.map_points[i]) continue;
                             best.add(i, hamming(d, frame.features.descriptors[i]));
                           }
                           if (!best.accept(kHammingLow, ratio)) continue;
                           if (best.best >= taken_distance[best.index]) continue;
                           taken_distance[best.index] = best.best;
                           taken_by[best.index] = k;
                         }
                       });
  for (std::size_t i = 0; i < frame.size(); ++i)
    if (taken_by[i] != BestTwo::kNone) matches.push_back({taken_by[i], i, taken_distance[i]});
  for (const auto& m : matches) {
    frame.map_points[m.b] = slots[m.a];
    frame.outlier[m.b] = false;
  }
  apply_rotation_check(kf_features, frame.features, matches, frame);
  int n = 0;
  for (const auto& m : matches)
    if (frame.map_points[m.b]) ++n;
  return n;
}

}  // namespace orbatlas
