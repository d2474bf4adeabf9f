#include "core/geometry/triangulate.h"

#include <Eigen/SVD>
#include <cmath>

namespace orbatlas {

bool triangulate_dlt(const Eigen::Vector2d& x1, const Eigen::Vector2d& x2, const Pose3& T_c1_w, const Pose3& T_c2_w,
                     Eigen::Vector3d* p_w) {
  const Eigen::Matrix<double, 3, 4> P1 = T_c1_w.matrix().topRows<3>();
  const Eigen::Matrix<double, 3, 4> P2 = T_c2_w.matrix().topRows<3>();
  Eigen::Matrix4d A;
  A.row(0) = x1.x() * P1.row(2) - P1.row(0);
  A.row(1) = x1.y() * P1.row(2) - P1.row(1);
  A.row(2) = x2.x() * P2.row(2) - P2.row(0);
  A.row(3) = x2.y() * P2.row(2) - P2.row(1);
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  if (std::abs(X(3)) < 1e-12) return false;
  *p_w = X.head<3>() / X(3);
  return p_w->allFinite();
}

}  // namespace orbatlas
