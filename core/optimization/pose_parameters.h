#pragma once
// A camera pose T_c_w as two Ceres parameter blocks: the rotation as an Eigen
// quaternion in memory order (x, y, z, w), on ceres::EigenQuaternionManifold, and
// the translation (3). p_c = q * p_w + t.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

#include "core/geometry/pose.h"

namespace orbatlas {

struct PoseParameters {
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};
  std::array<double, 3> t{0.0, 0.0, 0.0};

  static PoseParameters from_pose(const Pose3& T_c_w) {
    PoseParameters p;
    const Eigen::Quaterniond q = T_c_w.q.normalized();
    p.q = {q.x(), q.y(), q.z(), q.w()};
    p.t = {T_c_w.t.x(), T_c_w.t.y(), T_c_w.t.z()};
    return p;
  }
  Pose3 pose() const {
    return Pose3(Eigen::Map<const Eigen::Quaterniond>(q.data()), Eigen::Map<const Eigen::Vector3d>(t.data()));
  }
};

// p_c = T_c_w * p_w for T = double or ceres::Jet. The quaternion must be unit
// (the manifold keeps it so).
template <typename T>
void world_to_camera(const T* q_c_w, const T* t_c_w, const T* p_w, T* p_c) {
  const Eigen::Map<const Eigen::Quaternion<T>> q(q_c_w);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_c_w);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p(p_w);
  Eigen::Map<Eigen::Matrix<T, 3, 1>> out(p_c);
  out = q * p + t;
}

}  // namespace orbatlas
