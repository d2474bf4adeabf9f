#include "core/estimators/absolute_orientation.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "core/common/error.h"

namespace orbatlas {

std::optional<Sim3> horn_absolute_orientation(std::span<const Eigen::Vector3d> p1, std::span<const Eigen::Vector3d> p2,
                                              bool estimate_scale) {
  ORBATLAS_CHECK(p1.size() == p2.size(),
                 "absolute orientation: " << p1.size() << " points for " << p2.size() << " points");
  ORBATLAS_CHECK(p1.size() >= 3, "absolute orientation needs at least 3 point pairs, got " << p1.size());
  const double n = static_cast<double>(p1.size());

  Eigen::Vector3d c1 = Eigen::Vector3d::Zero(), c2 = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < p1.size(); ++i) {
    c1 += p1[i];
    c2 += p2[i];
  }
  c1 /= n;
  c2 /= n;

  // M = sum r2 r1^T: Horn's "left" set is 2 (the one rotated), "right" is 1.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  double ss1 = 0.0, ss2 = 0.0;
  for (std::size_t i = 0; i < p1.size(); ++i) {
    const Eigen::Vector3d r1 = p1[i] - c1;
    const Eigen::Vector3d r2 = p2[i] - c2;
    M += r2 * r1.transpose();
    ss1 += r1.squaredNorm();
    ss2 += r2.squaredNorm();
  }
  if (!(ss1 > 0.0) || !(ss2 > 0.0)) return std::nullopt;

  const double sxx = M(0, 0), sxy = M(0, 1), sxz = M(0, 2);
  const double syx = M(1, 0), syy = M(1, 1), syz = M(1, 2);
  const double szx = M(2, 0), szy = M(2, 1), szz = M(2, 2);
  Eigen::Matrix4d N;  // Horn (1987), eq. in section 4.A; quaternion order (w, x, y, z)
  N << sxx + syy + szz, syz - szy, szx - sxz, sxy - syx,  //
      syz - szy, sxx - syy - szz, sxy + syx, szx + sxz,   //
      szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy,  //
      sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz;

  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(N);  // eigenvalues ascending
  if (eig.info() != Eigen::Success) return std::nullopt;
  const Eigen::Vector4d lambda = eig.eigenvalues();
  // A repeated largest eigenvalue: collinear points, rotation about the line free.
  const double magnitude = std::max(std::abs(lambda(0)), std::abs(lambda(3)));
  if (!(lambda(3) - lambda(2) > 1e-12 * magnitude)) return std::nullopt;

  const Eigen::Vector4d e = eig.eigenvectors().col(3);
  const Eigen::Quaterniond q(e(0), e(1), e(2), e(3));
  const double s = estimate_scale ? std::sqrt(ss1 / ss2) : 1.0;
  const Eigen::Vector3d t = c1 - s * (q.normalized() * c2);
  return Sim3(q, t, s);
}

}  // namespace orbatlas
