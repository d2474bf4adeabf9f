#include "core/camera/kannala_brandt.h"

#include <algorithm>
#include <cmath>

#include "core/camera/camera_factory.h"

namespace orbatlas {
namespace {

const CameraCalibration& checked(const CameraCalibration& c) {
  check_calibration(c);
  return c;
}

}  // namespace

KannalaBrandt::KannalaBrandt(const CameraCalibration& calibration)
    : Camera(checked(calibration).width, calibration.height),
      calibration_(calibration),
      fx_(calibration.fx),
      fy_(calibration.fy),
      cx_(calibration.cx),
      cy_(calibration.cy),
      k1_(calibration.distortion[0]),
      k2_(calibration.distortion[1]),
      k3_(calibration.distortion[2]),
      k4_(calibration.distortion[3]),
      max_theta_(kMaxTheta) {
  // First angle where theta_d stops increasing (its derivative is 1 at theta = 0).
  constexpr int kSamples = 4000;
  double lo = 0.0;
  for (int i = 1; i <= kSamples; ++i) {
    const double theta = kMaxTheta * i / kSamples;
    if (distorted_theta_derivative(theta) <= 0.0) {
      double hi = theta;
      for (int b = 0; b < 100; ++b) {
        const double mid = 0.5 * (lo + hi);
        (distorted_theta_derivative(mid) > 0.0 ? lo : hi) = mid;
      }
      max_theta_ = lo;
      break;
    }
    lo = theta;
  }
}

double KannalaBrandt::distorted_theta(double theta) const {
  const double t2 = theta * theta;
  return theta * (1.0 + t2 * (k1_ + t2 * (k2_ + t2 * (k3_ + t2 * k4_))));
}

double KannalaBrandt::distorted_theta_derivative(double theta) const {
  const double t2 = theta * theta;
  return 1.0 + t2 * (3.0 * k1_ + t2 * (5.0 * k2_ + t2 * (7.0 * k3_ + t2 * 9.0 * k4_)));
}

Eigen::Vector3d KannalaBrandt::unproject(const Eigen::Vector2d& uv) const {
  const double xd = (uv.x() - cx_) / fx_;
  const double yd = (uv.y() - cy_) / fy_;
  const double theta_d = std::hypot(xd, yd);
  if (theta_d < 1e-15) return Eigen::Vector3d(xd, yd, 1.0).normalized();

  // Solve theta_d(theta) = theta_d on [0, max_theta_], where theta_d() increases:
  // Newton's method, falling back to bisection when a step leaves the bracket.
  constexpr int kMaxIterations = 100;
  constexpr double kTolerance = 1e-12;  // radians
  double lo = 0.0, hi = max_theta_;
  double theta = max_theta_;
  if (theta_d < distorted_theta(max_theta_)) {
    theta = std::min(theta_d, max_theta_);
    for (int it = 0; it < kMaxIterations; ++it) {
      const double f = distorted_theta(theta) - theta_d;
      if (f == 0.0) break;
      (f < 0.0 ? lo : hi) = theta;
      const double slope = distorted_theta_derivative(theta);
      double next = theta - f / slope;
      if (!(slope > 0.0) || !(next > lo && next < hi)) next = 0.5 * (lo + hi);
      const double step = std::abs(next - theta);
      theta = next;
      if (step < kTolerance) break;
    }
  }
  const double s = std::sin(theta) / theta_d;
  return Eigen::Vector3d(xd * s, yd * s, std::cos(theta));
}

Eigen::Matrix<double, 2, 3> KannalaBrandt::project_jacobian(const Eigen::Vector3d& p_c) const {
  const double x = p_c.x(), y = p_c.y(), z = p_c.z();
  const double r2 = x * x + y * y;
  Eigen::Matrix<double, 2, 3> j;
  if (r2 <= 1e-24 * z * z) {
    // On the optical axis the projection is f * (x, y) / z to first order.
    j << fx_ / z, 0.0, -fx_ * x / (z * z), 0.0, fy_ / z, -fy_ * y / (z * z);
    return j;
  }
  const double n2 = r2 + z * z;
  const double r = std::sqrt(r2);
  const double theta = std::atan2(r, z);
  const double theta_d = distorted_theta(theta);
  const double dtheta_d = distorted_theta_derivative(theta);
  // u - cx = fx * s * x with s = theta_d / r; ds/dx = x * a, ds/dy = y * a,
  // ds/dz = -dtheta_d / n2 (d theta/dx = z x / (r n2), d theta/dz = -r / n2).
  const double s = theta_d / r;
  const double a = dtheta_d * z / (r2 * n2) - s / r2;
  const double dz = -dtheta_d / n2;
  j(0, 0) = fx_ * (s + x * x * a);
  j(0, 1) = fx_ * x * y * a;
  j(0, 2) = fx_ * x * dz;
  j(1, 0) = fy_ * x * y * a;
  j(1, 1) = fy_ * (s + y * y * a);
  j(1, 2) = fy_ * y * dz;
  return j;
}

}  // namespace orbatlas
