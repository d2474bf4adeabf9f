#pragma once
// Pinhole camera with radial-tangential distortion: the model of OpenCV's
// cv::projectPoints with 4 (k1, k2, p1, p2) or 5 (k1, k2, p1, p2, k3) coefficients.
// Equations and limits: docs/cameras.md.
#include <Eigen/Core>

#include "core/camera/camera.h"

namespace orbatlas {

class PinholeRadTan final : public Camera {
 public:
  // Points closer to the image plane than this (z <= kMinDepth) are not projected.
  static constexpr double kMinDepth = 1e-9;

  // Throws Error when the calibration is invalid (see check_calibration()).
  explicit PinholeRadTan(const CameraCalibration& calibration);

  CameraModel model() const override { return CameraModel::kPinholeRadTan; }
  bool project(const Eigen::Vector3d& p_c, Eigen::Vector2d* uv) const override {
    return project_t(p_c.data(), uv->data());
  }
  Eigen::Vector3d unproject(const Eigen::Vector2d& uv) const override;
  Eigen::Matrix<double, 2, 3> project_jacobian(const Eigen::Vector3d& p_c) const override;
  CameraCalibration calibration() const override { return calibration_; }

  // The projection for T = double or ceres::Jet (autodiff): p[3] in the camera
  // frame -> uv[2]. Same result and validity as project().
  template <typename T>
  bool project_t(const T* p, T* uv) const;

  // Largest squared normalised radius (x/z)^2 + (y/z)^2 up to which the radial
  // distortion r * (1 + k1 r^2 + k2 r^4 + k3 r^6) is increasing; points beyond it
  // would fold back into the image and are rejected. Infinity when it always increases.
  double max_r2() const { return max_r2_; }

 private:
  CameraCalibration calibration_;
  double fx_, fy_, cx_, cy_;
  double k1_, k2_, p1_, p2_, k3_;  // k3_ = 0 with 4 coefficients
  double max_r2_;
  // No distortion at all (a rectified camera): the projection skips the
  // polynomial, whose terms would all be zero (the same values).
  bool undistorted_;
};

template <typename T>
bool PinholeRadTan::project_t(const T* p, T* uv) const {
  if (!(p[2] > T(kMinDepth))) return false;  // also rejects NaN
  const T inv_z = T(1.0) / p[2];
  const T x = p[0] * inv_z;
  const T y = p[1] * inv_z;
  if (undistorted_) {
    uv[0] = fx_ * x + cx_;
    uv[1] = fy_ * y + cy_;
    return true;
  }
  const T x2 = x * x;
  const T y2 = y * y;
  const T xy = x * y;
  const T r2 = x2 + y2;
  if (r2 > T(max_r2_)) return false;
  const T radial = T(1.0) + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
  const T xd = x * radial + (2.0 * p1_) * xy + p2_ * (r2 + 2.0 * x2);
  const T yd = y * radial + p1_ * (r2 + 2.0 * y2) + (2.0 * p2_) * xy;
  uv[0] = fx_ * xd + cx_;
  uv[1] = fy_ * yd + cy_;
  return true;
}

}  // namespace orbatlas
