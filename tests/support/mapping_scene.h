#pragma once
// Exact synthetic scenes for the mapping tests: points with descriptors seen
// by an undistorted pinhole camera, the features and keyframes they give from
// a pose, and poses by their position alone.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/features/feature_grid.h"
#include "core/features/keypoint_geometry.h"
#include "core/map/keyframe_data.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas::test {

inline CameraCalibration pinhole() {
  CameraCalibration c;
  c.model = CameraModel::kPinholeRadTan;
  c.fx = 450.0;
  c.fy = 450.0;
  c.cx = 376.0;
  c.cy = 240.0;
  c.distortion = {0, 0, 0, 0};
  c.width = 752;
  c.height = 480;
  return c;
}

struct Scene {
  std::unique_ptr<Camera> camera = make_camera(pinhole());
  std::vector<Eigen::Vector3d> points;
  std::vector<Descriptor> descriptors;
  FrameCamera cam() const {
    FrameCamera fc;
    fc.camera = camera.get();
    return fc;
  }
};

inline Scene make_scene(std::size_t n, std::uint32_t seed = 7) {
  Scene s;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-2.5, 2.5), y(-1.5, 1.5), z(3.0, 8.0);
  for (std::size_t i = 0; i < n; ++i) {
    s.points.emplace_back(x(rng), y(rng), z(rng));
    Descriptor d;
    for (auto& w : d) w = rng();
    s.descriptors.push_back(d);
  }
  return s;
}

// Features of the scene's visible points seen from T_w_c (level 0, angle 0, all
// under one vocabulary node); `index_of` maps keypoints back to points.
inline ImageFeatures observe(const Scene& s, const Pose3& T_w_c, std::vector<std::size_t>* index_of) {
  ImageFeatures f;
  f.width = 752;
  f.height = 480;
  const Pose3 T_c_w = T_w_c.inverse();
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    Eigen::Vector2d uv;
    const Eigen::Vector3d p_c = T_c_w * s.points[i];
    if (p_c.z() <= 0.1 || !s.camera->project(p_c, &uv) || !s.camera->in_image(uv, 20.0)) continue;
    Keypoint kp;
    kp.uv = uv.cast<float>();
    f.keypoints.push_back(kp);
    f.descriptors.push_back(s.descriptors[i]);
    index_of->push_back(i);
  }
  compute_keypoint_geometry(*s.camera, f.keypoints);
  return f;
}

inline KeyFrameData keyframe_data(const Scene& s, const Pose3& T_w_c, std::vector<std::size_t>* index_of) {
  KeyFrameData d;
  d.T_w_b = T_w_c;  // body = camera
  d.features = observe(s, T_w_c, index_of);
  for (std::uint32_t i = 0; i < d.features.keypoints.size(); ++i) d.feature_vector[0].push_back(i);
  d.grid = FeatureGrid(d.features);
  return d;
}

inline Pose3 at(double x, double y, double z) {
  return Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, z));
}

}  // namespace orbatlas::test
