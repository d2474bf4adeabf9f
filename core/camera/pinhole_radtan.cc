#include "core/camera/pinhole_radtan.h"

#include <cmath>
#include <limits>

#include "core/camera/camera_factory.h"

namespace orbatlas {
namespace {

const CameraCalibration& checked(const CameraCalibration& c) {
  check_calibration(c);
  return c;
}

// d/dr of r * (1 + k1 r^2 + k2 r^4 + k3 r^6), as a function of u = r^2.
double radial_slope(double u, double k1, double k2, double k3) {
  return 1.0 + u * (3.0 * k1 + u * (5.0 * k2 + u * 7.0 * k3));
}

// Smallest u = r^2 > 0 where the radial mapping stops increasing, or infinity.
double first_fold_r2(double k1, double k2, double k3) {
  constexpr double kFirst = 1e-6, kLast = 1e8, kRatio = 1.01;
  double lo = 0.0;
  for (double u = kFirst; u <= kLast; u *= kRatio) {
    if (radial_slope(u, k1, k2, k3) <= 0.0) {
      double hi = u;
      for (int i = 0; i < 100; ++i) {
        const double mid = 0.5 * (lo + hi);
        (radial_slope(mid, k1, k2, k3) > 0.0 ? lo : hi) = mid;
      }
      return lo;
    }
    lo = u;
  }
  return std::numeric_limits<double>::infinity();
}

// Distorted normalised point of (x, y) and its 2x2 Jacobian.
struct Distorted {
  double xd, yd;
  double j00, j01, j10, j11;
};

}  // namespace

PinholeRadTan::PinholeRadTan(const CameraCalibration& calibration)
    : Camera(checked(calibration).width, calibration.height),
      calibration_(calibration),
      fx_(calibration.fx),
      fy_(calibration.fy),
      cx_(calibration.cx),
      cy_(calibration.cy),
      k1_(calibration.distortion[0]),
      k2_(calibration.distortion[1]),
      p1_(calibration.distortion[2]),
      p2_(calibration.distortion[3]),
      k3_(calibration.distortion.size() > 4 ? calibration.distortion[4] : 0.0),
      max_r2_(first_fold_r2(k1_, k2_, k3_)),
      undistorted_(k1_ == 0.0 && k2_ == 0.0 && p1_ == 0.0 && p2_ == 0.0 && k3_ == 0.0) {}

Eigen::Vector3d PinholeRadTan::unproject(const Eigen::Vector2d& uv) const {
  const double xd = (uv.x() - cx_) / fx_;
  const double yd = (uv.y() - cy_) / fy_;

  const auto distort = [this](double x, double y) {
    const double x2 = x * x, y2 = y * y, xy = x * y, r2 = x2 + y2;
    const double radial = 1.0 + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
    const double dradial = k1_ + r2 * (2.0 * k2_ + r2 * 3.0 * k3_);  // d radial / d r2
    const double cross = 2.0 * xy * dradial + 2.0 * p1_ * x + 2.0 * p2_ * y;
    return Distorted{x * radial + 2.0 * p1_ * xy + p2_ * (r2 + 2.0 * x2),
                     y * radial + p1_ * (r2 + 2.0 * y2) + 2.0 * p2_ * xy,
                     radial + 2.0 * x2 * dradial + 2.0 * p1_ * y + 6.0 * p2_ * x,
                     cross,
                     cross,
                     radial + 2.0 * y2 * dradial + 6.0 * p1_ * y + 2.0 * p2_ * x};
  };

  // Newton's method on distort(x, y) = (xd, yd) from the distorted point, with
  // step halving when a full step does not reduce the residual.
  constexpr int kMaxIterations = 50;
  constexpr int kMaxHalvings = 20;
  constexpr double kStepTolerance = 1e-10;  // normalised coordinates
  double x = xd, y = yd;
  Distorted d = distort(x, y);
  double ex = d.xd - xd, ey = d.yd - yd;
  double err2 = ex * ex + ey * ey;
  for (int it = 0; it < kMaxIterations && err2 > 0.0; ++it) {
    const double det = d.j00 * d.j11 - d.j01 * d.j10;
    if (!(std::abs(det) > 1e-300)) break;
    const double sx = -(d.j11 * ex - d.j01 * ey) / det;
    const double sy = -(d.j00 * ey - d.j10 * ex) / det;
    double step = 1.0;
    double nx = x + sx, ny = y + sy;
    Distorted nd = distort(nx, ny);
    double nex = nd.xd - xd, ney = nd.yd - yd;
    double nerr2 = nex * nex + ney * ney;
    for (int h = 0; h < kMaxHalvings && !(nerr2 < err2); ++h) {
      step *= 0.5;
      nx = x + step * sx;
      ny = y + step * sy;
      nd = distort(nx, ny);
      nex = nd.xd - xd;
      ney = nd.yd - yd;
      nerr2 = nex * nex + ney * ney;
    }
    if (!(nerr2 < err2)) break;  // no progress possible: keep the best point
    x = nx;
    y = ny;
    d = nd;
    ex = nex;
    ey = ney;
    err2 = nerr2;
    if (step * std::sqrt(sx * sx + sy * sy) < kStepTolerance) break;
  }
  return Eigen::Vector3d(x, y, 1.0).normalized();
}

Eigen::Matrix<double, 2, 3> PinholeRadTan::project_jacobian(const Eigen::Vector3d& p_c) const {
  const double inv_z = 1.0 / p_c.z();
  const double x = p_c.x() * inv_z, y = p_c.y() * inv_z;
  const double x2 = x * x, y2 = y * y, xy = x * y, r2 = x2 + y2;
  const double radial = 1.0 + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
  const double dradial = k1_ + r2 * (2.0 * k2_ + r2 * 3.0 * k3_);  // d radial / d r2
  // d(xd, yd) / d(x, y)
  const double d00 = radial + 2.0 * x2 * dradial + 2.0 * p1_ * y + 6.0 * p2_ * x;
  const double d01 = 2.0 * xy * dradial + 2.0 * p1_ * x + 2.0 * p2_ * y;
  const double d11 = radial + 2.0 * y2 * dradial + 6.0 * p1_ * y + 2.0 * p2_ * x;
  // d(x, y) / d(p) = [1/z 0 -x/z; 0 1/z -y/z]
  Eigen::Matrix<double, 2, 3> j;
  j(0, 0) = fx_ * d00 * inv_z;
  j(0, 1) = fx_ * d01 * inv_z;
  j(0, 2) = -fx_ * (d00 * x + d01 * y) * inv_z;
  j(1, 0) = fy_ * d01 * inv_z;
  j(1, 1) = fy_ * d11 * inv_z;
  j(1, 2) = -fy_ * (d01 * x + d11 * y) * inv_z;
  return j;
}

}  // namespace orbatlas
