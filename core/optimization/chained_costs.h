#pragma once
// The reprojection costs the optimisers use: same values and derivatives as
// ceres::AutoDiffCostFunction over PoseOnlyCost / PosePointCost, but several times
// cheaper. Only the camera part is differentiated automatically (the Residual
// functor, i.e. Camera::project_t, on 3-dimensional Jets, so every camera model
// works), and it is chained with the analytic derivatives of p_c = R(q) p_w + t.
// Autodiff over all 7 or 10 parameters spent ~1 us per residual in Jet arithmetic.
#include <ceres/jet.h>
#include <ceres/sized_cost_function.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace orbatlas {

// d(q * p) / d(x, y, z, w) for the Eigen quaternion (memory order), at unit q:
// q * p = p + 2 w (v x p) + 2 v x (v x p) with v = (x, y, z).
inline Eigen::Matrix<double, 3, 4> rotate_point_jacobian(const Eigen::Quaterniond& q, const Eigen::Vector3d& p) {
  const Eigen::Vector3d v = q.vec();
  const double w = q.w();
  Eigen::Matrix3d p_hat;
  p_hat << 0.0, -p.z(), p.y(), p.z(), 0.0, -p.x(), -p.y(), p.x(), 0.0;
  Eigen::Matrix<double, 3, 4> J;
  J.leftCols<3>() =
      -2.0 * w * p_hat + 2.0 * (v.dot(p) * Eigen::Matrix3d::Identity() + v * p.transpose() - 2.0 * p * v.transpose());
  J.col(3) = 2.0 * v.cross(p);
  return J;
}

// r and dr/dp_c at p_c (dr_dpc may be null: value only).
template <class Residual>
bool camera_residual_and_jacobian(const Residual& residual, const Eigen::Vector3d& p_c, double* r,
                                  Eigen::Matrix<double, Residual::kResiduals, 3>* dr_dpc) {
  if (dr_dpc == nullptr) return residual(p_c.data(), r);
  using Jet = ceres::Jet<double, 3>;
  const Jet p_jet[3] = {Jet(p_c.x(), 0), Jet(p_c.y(), 1), Jet(p_c.z(), 2)};
  Jet r_jet[Residual::kResiduals];
  if (!residual(p_jet, r_jet)) return false;
  for (int i = 0; i < Residual::kResiduals; ++i) {
    r[i] = r_jet[i].a;
    dr_dpc->row(i) = r_jet[i].v.transpose();
  }
  return true;
}

// Parameter blocks (q_c_w[4], t_c_w[3]); the world point is a constant.
template <class Residual>
class PoseOnlyChainCost final : public ceres::SizedCostFunction<Residual::kResiduals, 4, 3> {
 public:
  static constexpr int kR = Residual::kResiduals;

  PoseOnlyChainCost(const Residual& residual, const Eigen::Vector3d& p_w) : residual_(residual), p_w_(p_w) {}

  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
    const Eigen::Vector3d p_c = q * p_w_ + t;
    if (jacobians == nullptr || (jacobians[0] == nullptr && jacobians[1] == nullptr))
      return camera_residual_and_jacobian<Residual>(residual_, p_c, residuals, nullptr);
    Eigen::Matrix<double, kR, 3> dr_dpc;
    if (!camera_residual_and_jacobian(residual_, p_c, residuals, &dr_dpc)) return false;
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 4, Eigen::RowMajor>> j_q(jacobians[0]);
      j_q = dr_dpc * rotate_point_jacobian(q, p_w_);
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 3, Eigen::RowMajor>> j_t(jacobians[1]);
      j_t = dr_dpc;
    }
    return true;
  }

 private:
  Residual residual_;
  Eigen::Vector3d p_w_;
};

// Parameter blocks (q_c_w[4], t_c_w[3], p_w[3]).
template <class Residual>
class PosePointChainCost final : public ceres::SizedCostFunction<Residual::kResiduals, 4, 3, 3> {
 public:
  static constexpr int kR = Residual::kResiduals;

  explicit PosePointChainCost(const Residual& residual) : residual_(residual) {}

  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
    const Eigen::Map<const Eigen::Vector3d> p_w(parameters[2]);
    const Eigen::Vector3d p_c = q * p_w + t;
    if (jacobians == nullptr || (jacobians[0] == nullptr && jacobians[1] == nullptr && jacobians[2] == nullptr))
      return camera_residual_and_jacobian<Residual>(residual_, p_c, residuals, nullptr);
    Eigen::Matrix<double, kR, 3> dr_dpc;
    if (!camera_residual_and_jacobian(residual_, p_c, residuals, &dr_dpc)) return false;
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 4, Eigen::RowMajor>> j_q(jacobians[0]);
      j_q = dr_dpc * rotate_point_jacobian(q, p_w);
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 3, Eigen::RowMajor>> j_t(jacobians[1]);
      j_t = dr_dpc;
    }
    if (jacobians[2] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, kR, 3, Eigen::RowMajor>> j_p(jacobians[2]);
      j_p = dr_dpc * q.toRotationMatrix();
    }
    return true;
  }

 private:
  Residual residual_;
};

}  // namespace orbatlas
