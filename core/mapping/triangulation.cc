#include "core/mapping/triangulation.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/features/matching.h"
#include "core/map/map_point_update.h"
#include "core/optimization/chi2.h"

namespace orbatlas {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

struct Candidate {
  std::size_t i1, i2;
  int distance;
};

// Squared distance (pixels, image 2) of keypoint 2 from the epipolar line of keypoint 1.
double epipolar_distance2(const Eigen::Matrix3d& F12, const Eigen::Vector2f& uv1, const Eigen::Vector2f& uv2) {
  const Eigen::Vector3d x1(uv1.x(), uv1.y(), 1.0);
  const Eigen::Vector3d line = F12.transpose() * x1;  // x1^T F12 x2 = 0
  const double num = line.x() * uv2.x() + line.y() * uv2.y() + line.z();
  const double den = line.x() * line.x() + line.y() * line.y();
  return den > 0.0 ? num * num / den : std::numeric_limits<double>::infinity();
}

// Reprojection chi2 test of p_c against a keyframe's keypoint (with its stereo column).
bool reprojects(const KeyFrame& kf, std::size_t slot, const Eigen::Vector3d& p_c, const FrameCamera& cam) {
  Eigen::Vector2d uv;
  if (!cam.camera->project(p_c, &uv)) return false;
  const Keypoint& kp = kf.keypoint(slot);
  const double sigma2 = cam.pyramid.sigma2(kp.level);
  double e2 = (uv - kp.uv.cast<double>()).squaredNorm();
  const float ur = kf.u_right(slot);
  if (ur >= 0.0f && cam.bf > 0.0) {
    const double er = uv.x() - cam.bf / p_c.z() - ur;
    return (e2 + er * er) / sigma2 <= kChi2Stereo95;
  }
  return e2 / sigma2 <= kChi2Mono95;
}

}  // namespace

TriangulationStats triangulate_pair(Map& map, const std::shared_ptr<KeyFrame>& kf1,
                                    const std::shared_ptr<KeyFrame>& kf2, const FrameCamera& cam,
                                    std::vector<std::shared_ptr<MapPoint>>* created) {
  TriangulationStats stats;
  const Pose3 T_w_c1 = kf1->T_w_c(), T_w_c2 = kf2->T_w_c();
  const Pose3 T_c1_w = T_w_c1.inverse(), T_c2_w = T_w_c2.inverse();
  const double baseline = (T_w_c2.t - T_w_c1.t).norm();
  const double stereo_baseline = cam.baseline();
  if (stereo_baseline > 0.0 && baseline < stereo_baseline) return stats;  // the stereo pair already does better
  if (stereo_baseline <= 0.0) {
    // A single camera: too short a baseline for the scene's depth gives no
    // parallax (a keyframe without points yet cannot say: tried).
    const double median = median_scene_depth(*kf2);
    if (median > 0.0 && baseline / median < 0.01) return stats;
  }

  const CameraCalibration calib = cam.camera->calibration();
  Eigen::Matrix3d K;
  K << calib.fx, 0, calib.cx, 0, calib.fy, calib.cy, 0, 0, 1;
  const Pose3 T_c1_c2 = T_c1_w * T_w_c2;
  const Eigen::Matrix3d E12 = skew(T_c1_c2.t) * T_c1_c2.rotation();
  const Eigen::Matrix3d Kinv = K.inverse();
  const Eigen::Matrix3d F12 = Kinv.transpose() * E12 * Kinv;

  const auto slots1 = kf1->slots(), slots2 = kf2->slots();
  const auto& f1 = kf1->features();
  const auto& f2 = kf2->features();
  std::vector<Candidate> candidates;
  std::vector<int> taken(f2.keypoints.size(), 257);
  std::vector<std::size_t> owner(f2.keypoints.size(), BestTwo::kNone);

  for_each_common_node(kf1->feature_vector(), kf2->feature_vector(), [&](const auto& node1, const auto& node2) {
    for (const std::uint32_t i1 : node1) {
      if (slots1[i1]) continue;
      const Keypoint& kp1 = f1.keypoints[i1];
      int best = kHammingLow + 1;
      std::size_t best_i2 = BestTwo::kNone;
      for (const std::uint32_t i2 : node2) {
        if (slots2[i2]) continue;
        const int d = hamming(f1.descriptors[i1], f2.descriptors[i2]);
        if (d > kHammingLow || d >= best) continue;
        const Keypoint& kp2 = f2.keypoints[i2];
        if (epipolar_distance2(F12, kp1.uv_undistorted, kp2.uv_undistorted) >= 3.84 * cam.pyramid.sigma2(kp2.level))
          continue;
        best = d;
        best_i2 = i2;
      }
      if (best_i2 == BestTwo::kNone || best >= taken[best_i2]) continue;
      taken[best_i2] = best;
      owner[best_i2] = i1;
    }
  });
  std::vector<FeatureMatch> matches;
  for (std::size_t i2 = 0; i2 < owner.size(); ++i2)
    if (owner[i2] != BestTwo::kNone) matches.push_back({owner[i2], i2, taken[i2]});
  keep_rotation_consistent(f1, f2, matches);
  stats.matches = static_cast<int>(matches.size());

  const Eigen::Matrix3d R_w_c1 = T_w_c1.rotation(), R_w_c2 = T_w_c2.rotation();
  const double ratio_factor = 1.5 * cam.pyramid.scale_factor;
  for (const auto& m : matches) {
    const Keypoint& kp1 = f1.keypoints[m.a];
    const Keypoint& kp2 = f2.keypoints[m.b];
    const float z1 = kf1->depth(m.a), z2 = kf2->depth(m.b);
    const bool stereo1 = z1 > 0.0f, stereo2 = z2 > 0.0f;
    const Eigen::Vector3d ray1 = R_w_c1 * kp1.bearing, ray2 = R_w_c2 * kp2.bearing;
    const double cos_rays = ray1.dot(ray2) / (ray1.norm() * ray2.norm());
    const double cos_stereo1 = stereo1 ? std::cos(2.0 * std::atan2(stereo_baseline / 2.0, z1)) : 2.0;
    const double cos_stereo2 = stereo2 ? std::cos(2.0 * std::atan2(stereo_baseline / 2.0, z2)) : 2.0;
    const double cos_stereo = std::min(cos_stereo1, cos_stereo2);

    Eigen::Vector3d p_w;
    if (cos_rays < cos_stereo && cos_rays > 0.0 && (stereo1 || stereo2 || cos_rays < 0.9998)) {
      const Eigen::Vector2d x1 = kp1.bearing.head<2>() / kp1.bearing.z();
      const Eigen::Vector2d x2 = kp2.bearing.head<2>() / kp2.bearing.z();
      if (!triangulate_dlt(x1, x2, T_c1_w, T_c2_w, &p_w)) continue;
    } else if (stereo1 && cos_stereo1 < cos_stereo2) {
      p_w = T_w_c1 * (kp1.bearing * (static_cast<double>(z1) / kp1.bearing.z()));
    } else if (stereo2 && cos_stereo2 < cos_stereo1) {
      p_w = T_w_c2 * (kp2.bearing * (static_cast<double>(z2) / kp2.bearing.z()));
    } else {
      continue;  // too little parallax
    }
    const Eigen::Vector3d p_c1 = T_c1_w * p_w, p_c2 = T_c2_w * p_w;
    if (p_c1.z() <= 0.0 || p_c2.z() <= 0.0) continue;
    if (!reprojects(*kf1, m.a, p_c1, cam) || !reprojects(*kf2, m.b, p_c2, cam)) continue;
    const double dist1 = (p_w - T_w_c1.t).norm(), dist2 = (p_w - T_w_c2.t).norm();
    if (dist1 <= 0.0 || dist2 <= 0.0) continue;
    const double ratio_dist = dist2 / dist1;
    const double ratio_octave = cam.pyramid.scale(kp1.level) / cam.pyramid.scale(kp2.level);
    if (ratio_dist * ratio_factor < ratio_octave || ratio_dist > ratio_octave * ratio_factor) continue;

    MapPointData data;
    data.p_w = p_w;
    data.descriptor = f1.descriptors[m.a];
    auto mp = map.new_map_point(data);
    const bool ok1 = add_observation_if_free(*kf1, m.a, mp);
    const bool ok2 = ok1 && add_observation_if_free(*kf2, m.b, mp);
    if (!ok1 || !ok2) {
      map.cull_map_point(mp->id());
      continue;
    }
    mp->set_reference_keyframe(kf1);
    update_map_point(*mp, cam.pyramid);
    ++stats.created;
    if (created) created->push_back(std::move(mp));
  }
  return stats;
}

}  // namespace orbatlas
