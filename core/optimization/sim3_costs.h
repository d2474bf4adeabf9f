#pragma once
// Reprojection costs of a similarity S_1_2 (ORB-SLAM's EdgeSim3ProjectXYZ and
// EdgeInverseSim3ProjectXYZ), on parameter blocks (q_1_2[4] in Eigen memory order
// x, y, z, w on EigenQuaternionManifold, t_1_2[3], log_s[1]) with s = exp(log_s),
// so the scale stays positive and the scale-fixed case is one constant block:
//
//   forward:  p_c1 = s R p_c2 + t             observed in image 1 (camera 1)
//   inverse:  p_c2 = (1/s) R^T (p_c1 - t)     observed in image 2 (camera 2)
//
// residual = (uv_observed - project(p_c)) / sigma (MonoResidual of
// reprojection_residuals.h), so its squared norm is the chi2. As chained_costs.h,
// only the camera is differentiated automatically (3-dim Jets of p_c), chained
// with the analytic derivatives of p_c with respect to (q, t, log_s).
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <memory>

#include "core/camera/camera.h"
#include "core/optimization/chained_costs.h"

namespace orbatlas {

enum class Sim3Projection {
  kForward,  // S_1_2 * p_c2 into image 1
  kInverse,  // S_1_2^-1 * p_c1 into image 2
};

template <class Residual>
class Sim3ProjectionCost final : public ceres::SizedCostFunction<Residual::kResiduals, 4, 3, 1> {
 public:
  static constexpr int kR = Residual::kResiduals;

  // `p`: p_c2 (forward) or p_c1 (inverse).
  Sim3ProjectionCost(const Residual& residual, const Eigen::Vector3d& p, Sim3Projection direction)
      : residual_(residual), p_(p), direction_(direction) {}

  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
    const double s = std::exp(parameters[2][0]);
    Eigen::Vector3d p_c;
    Eigen::Matrix<double, 3, 4> dpc_dq;
    Eigen::Matrix3d dpc_dt;
    Eigen::Vector3d dpc_dls;
    const bool want =
        jacobians != nullptr && (jacobians[0] != nullptr || jacobians[1] != nullptr || jacobians[2] != nullptr);
    if (direction_ == Sim3Projection::kForward) {
      const Eigen::Vector3d Rp = q * p_;
      p_c = s * Rp + t;
      if (want) {
        dpc_dq = s * rotate_point_jacobian(q, p_);
        dpc_dt.setIdentity();
        dpc_dls = s * Rp;  // d(exp(l) R p)/dl
      }
    } else {
      const Eigen::Quaterniond qc = q.conjugate();
      const Eigen::Vector3d y = p_ - t;
      p_c = (qc * y) / s;
      if (want) {
        // d(conj(q) * y)/dq: the rotation Jacobian at conj(q), times d conj(q)/dq = diag(-1, -1, -1, 1).
        dpc_dq = rotate_point_jacobian(qc, y) / s;
        dpc_dq.leftCols<3>() *= -1.0;
        dpc_dt = -qc.toRotationMatrix() / s;
        dpc_dls = -p_c;  // d(exp(-l) R^T y)/dl
      }
    }
    if (!want) return camera_residual_and_jacobian<Residual>(residual_, p_c, residuals, nullptr);
    Eigen::Matrix<double, kR, 3> dr_dpc;
    if (!camera_residual_and_jacobian(residual_, p_c, residuals, &dr_dpc)) return false;
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 4, Eigen::RowMajor>> j(jacobians[0]);
      j = dr_dpc * dpc_dq;
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 3, Eigen::RowMajor>> j(jacobians[1]);
      j = dr_dpc * dpc_dt;
    }
    if (jacobians[2] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 1>> j(jacobians[2]);
      j = dr_dpc * dpc_dls;
    }
    return true;
  }

 private:
  Residual residual_;
  Eigen::Vector3d p_;
  Sim3Projection direction_;
};

// The cost for `camera`'s model (dispatch on Camera::model()); the cost keeps a
// pointer to the camera, which must outlive it. Throws Error on a non-positive
// sigma2 or an unsupported model.
std::unique_ptr<ceres::CostFunction> make_sim3_projection_cost(const Camera& camera, const Eigen::Vector3d& p,
                                                               const Eigen::Vector2d& uv, double level_sigma2,
                                                               Sim3Projection direction);

}  // namespace orbatlas
