#pragma once
// Equidistant fisheye camera (Kannala-Brandt with k1..k4): the model of OpenCV's
// cv::fisheye::projectPoints, EuRoC's "equidistant" and ORB-SLAM3's "KannalaBrandt8".
// Equations and limits: docs/cameras.md.
#include <Eigen/Core>
#include <cmath>

#include "core/camera/camera.h"

namespace orbatlas {

class KannalaBrandt final : public Camera {
 public:
  // Throws Error when the calibration is invalid (see check_calibration()).
  explicit KannalaBrandt(const CameraCalibration& calibration);

  CameraModel model() const override { return CameraModel::kKannalaBrandt; }
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

  // Largest angle from the optical axis (radians) that is projected: where
  // theta_d(theta) stops increasing, and never more than kMaxTheta.
  double max_theta() const { return max_theta_; }
  static constexpr double kMaxTheta = 3.14059265358979;  // pi - 1e-3

 private:
  double distorted_theta(double theta) const;  // theta_d(theta)
  double distorted_theta_derivative(double theta) const;

  CameraCalibration calibration_;
  double fx_, fy_, cx_, cy_;
  double k1_, k2_, k3_, k4_;
  double max_theta_;
};

template <typename T>
bool KannalaBrandt::project_t(const T* p, T* uv) const {
  using std::atan2;
  using std::sqrt;
  const T r2 = p[0] * p[0] + p[1] * p[1];
  const T z2 = p[2] * p[2];
  if (!(r2 + z2 > T(0.0))) return false;  // zero norm or NaN
  if (r2 <= 1e-24 * z2) {
    // On the optical axis: theta_d / r -> 1 / z (the distortion terms are below 1e-24).
    if (!(p[2] > T(0.0))) return false;  // straight behind the camera
    uv[0] = fx_ * p[0] / p[2] + cx_;
    uv[1] = fy_ * p[1] / p[2] + cy_;
    return true;
  }
  const T r = sqrt(r2);
  const T theta = atan2(r, p[2]);
  if (theta > T(max_theta_)) return false;
  const T t2 = theta * theta;
  const T theta_d = theta * (T(1.0) + t2 * (k1_ + t2 * (k2_ + t2 * (k3_ + t2 * k4_))));
  const T scale = theta_d / r;
  uv[0] = fx_ * scale * p[0] + cx_;
  uv[1] = fy_ * scale * p[1] + cy_;
  return true;
}

}  // namespace orbatlas
