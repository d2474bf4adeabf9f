#include "core/imu/inertial_initialization.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <cmath>
#include <memory>

#include "core/common/error.h"
#include "core/geometry/so3.h"

namespace orbatlas {
namespace {

template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;

template <typename T>
Mat3<T> exp_so3(const Vec3<T>& w) {
  Mat3<T> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // column-major, as Eigen's default
  return R;
}

template <typename T>
Vec3<T> log_so3(const Mat3<T>& R) {
  Vec3<T> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

// The inertial residual between keyframes i and j (Preintegration::residual),
// whitened by the preintegration's information, as a function of both
// velocities, the window's biases, the gravity direction and the log scale.
struct InertialEdge {
  Eigen::Matrix3d Ri, Ri_T_Rj;
  Eigen::Vector3d pi_body, pj_body, lever_i, lever_j;  // IMU position = s * p_body + lever
  double dt = 0.0;
  Eigen::Matrix3d dR, dR_dbg, dv_dbg, dv_dba, dp_dbg, dp_dba;
  Eigen::Vector3d dv, dp, bg0, ba0;
  Eigen::Matrix<double, 9, 9> sqrt_information;
  Eigen::Matrix3d R_wg0;
  double gravity = 9.81;

  template <typename T>
  bool operator()(const T* vi_, const T* vj_, const T* bg_, const T* ba_, const T* gdir_, const T* log_s_,
                  T* out) const {
    const Eigen::Map<const Vec3<T>> vi(vi_), vj(vj_), bg(bg_), ba(ba_);
    const Vec3<T> dbg = bg - bg0.cast<T>(), dba = ba - ba0.cast<T>();
    const Vec3<T> tilt(gdir_[0], gdir_[1], T(0));
    const Vec3<T> g = R_wg0.cast<T>() * exp_so3<T>(tilt) * Vec3<T>(T(0), T(0), T(-gravity));
    const T s = ceres::exp(log_s_[0]);
    const Vec3<T> pi = s * pi_body.cast<T>() + lever_i.cast<T>();
    const Vec3<T> pj = s * pj_body.cast<T>() + lever_j.cast<T>();
    const Mat3<T> dR_b = dR.cast<T>() * exp_so3<T>(Vec3<T>(dR_dbg.cast<T>() * dbg));
    const Vec3<T> dv_b = dv.cast<T>() + dv_dbg.cast<T>() * dbg + dv_dba.cast<T>() * dba;
    const Vec3<T> dp_b = dp.cast<T>() + dp_dbg.cast<T>() * dbg + dp_dba.cast<T>() * dba;
    const Mat3<T> Rit = Ri.transpose().cast<T>();
    const T t = T(dt);
    Eigen::Matrix<T, 9, 1> r;
    r.template segment<3>(0) = log_so3<T>(Mat3<T>(dR_b.transpose() * Ri_T_Rj.cast<T>()));
    r.template segment<3>(3) = Rit * (vj - vi - g * t) - dv_b;
    r.template segment<3>(6) = Rit * (pj - pi - vi * t - T(0.5) * g * t * t) - dp_b;
    Eigen::Map<Eigen::Matrix<T, 9, 1>> whitened(out);
    whitened = sqrt_information.cast<T>() * r;
    return true;
  }
};

struct BiasPrior {
  double weight = 1.0;
  template <typename T>
  bool operator()(const T* b, T* out) const {
    for (int k = 0; k < 3; ++k) out[k] = T(weight) * b[k];
    return true;
  }
};

// Rotation taking the gravity frame's down (0, 0, -1) to `down_w`.
Eigen::Matrix3d gravity_frame_to(const Eigen::Vector3d& down_w) {
  const Eigen::Vector3d down_g(0.0, 0.0, -1.0);
  const Eigen::Vector3d axis = down_g.cross(down_w);
  const double angle = std::atan2(axis.norm(), down_g.dot(down_w));
  if (axis.norm() < 1e-12)
    return angle > 1.0 ? so3_exp(Eigen::Vector3d(M_PI, 0.0, 0.0)).toRotationMatrix() : Eigen::Matrix3d::Identity();
  return so3_exp(axis.normalized() * angle).toRotationMatrix();
}

}  // namespace

void InertialInitOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(gravity) && gravity > 0.0, "inertial init: gravity must be > 0, not " << gravity);
  ORBATLAS_CHECK(std::isfinite(gyro_bias_prior) && gyro_bias_prior >= 0.0,
                 "inertial init: gyro_bias_prior must be >= 0, not " << gyro_bias_prior);
  ORBATLAS_CHECK(std::isfinite(accel_bias_prior) && accel_bias_prior >= 0.0,
                 "inertial init: accel_bias_prior must be >= 0, not " << accel_bias_prior);
  ORBATLAS_CHECK(max_iterations > 0, "inertial init: max_iterations must be > 0, not " << max_iterations);
}

InertialInitResult initialize_inertial(const std::vector<Pose3>& T_w_b,
                                       const std::vector<Preintegration>& preintegrated, const Pose3& T_b_i,
                                       const InertialInitOptions& options) {
  options.check();
  const std::size_t n = T_w_b.size();
  ORBATLAS_CHECK(n >= 3, "inertial init needs at least 3 keyframes, not " << n);
  ORBATLAS_CHECK(preintegrated.size() + 1 == n,
                 "inertial init: " << preintegrated.size() << " preintegrations for " << n << " keyframes");
  const Eigen::Matrix3d R_b_i = T_b_i.rotation();
  std::vector<Eigen::Matrix3d> R(n);
  std::vector<Eigen::Vector3d> lever(n);
  for (std::size_t k = 0; k < n; ++k) {
    R[k] = T_w_b[k].rotation() * R_b_i;
    lever[k] = T_w_b[k].rotation() * T_b_i.t;
  }
  const ImuBias bias0 = preintegrated.front().bias();

  // Initial guesses (ORB-SLAM3): velocities from the positions; gravity from the
  // rotated velocity increments, whose sum over the window is about g * T minus
  // the change of velocity.
  InertialInitResult result;
  result.velocities.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t a = k == 0 ? 0 : k - 1, b = k + 1 == n ? n - 1 : k + 1;
    double span = 0.0;
    for (std::size_t m = a; m < b; ++m) span += preintegrated[m].dt();
    result.velocities[k] = (T_w_b[b].t + lever[b] - T_w_b[a].t - lever[a]) / span;
  }
  Eigen::Vector3d down = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k + 1 < n; ++k) down -= R[k] * preintegrated[k].delta_v();
  ORBATLAS_CHECK(down.norm() > 1e-9, "inertial init: the IMU increments give no gravity direction");
  const Eigen::Matrix3d R_wg0 = gravity_frame_to(down.normalized());

  std::array<double, 2> gdir{0.0, 0.0};
  std::array<double, 1> log_s{0.0};
  Eigen::Vector3d bg = bias0.gyro, ba = bias0.accel;

  std::vector<std::unique_ptr<ceres::CostFunction>> costs;  // outlive the problem
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const Preintegration& pre = preintegrated[k];
    ORBATLAS_CHECK(pre.bias() == bias0, "inertial init: the preintegrations must share one bias");
    auto edge = std::make_unique<InertialEdge>();
    edge->Ri = R[k];
    edge->Ri_T_Rj = R[k].transpose() * R[k + 1];
    edge->pi_body = T_w_b[k].t;
    edge->pj_body = T_w_b[k + 1].t;
    edge->lever_i = lever[k];
    edge->lever_j = lever[k + 1];
    edge->dt = pre.dt();
    edge->dR = pre.delta_R();
    edge->dv = pre.delta_v();
    edge->dp = pre.delta_p();
    edge->dR_dbg = pre.dR_dbg();
    edge->dv_dbg = pre.dv_dbg();
    edge->dv_dba = pre.dv_dba();
    edge->dp_dbg = pre.dp_dbg();
    edge->dp_dba = pre.dp_dba();
    edge->bg0 = bias0.gyro;
    edge->ba0 = bias0.accel;
    const Eigen::Matrix<double, 9, 9> information = pre.covariance().inverse();
    ORBATLAS_CHECK(information.allFinite(), "inertial init: a preintegration's covariance is singular");
    edge->sqrt_information = Eigen::LLT<Eigen::Matrix<double, 9, 9>>(information).matrixU();
    edge->R_wg0 = R_wg0;
    edge->gravity = options.gravity;
    costs.push_back(std::make_unique<ceres::AutoDiffCostFunction<InertialEdge, 9, 3, 3, 3, 3, 2, 1>>(
        edge.release()));  // the cost owns its functor
    problem.AddResidualBlock(costs.back().get(), nullptr, result.velocities[k].data(), result.velocities[k + 1].data(),
                             bg.data(), ba.data(), gdir.data(), log_s.data());
  }
  costs.emplace_back(
      new ceres::AutoDiffCostFunction<BiasPrior, 3, 3>(new BiasPrior{std::sqrt(options.gyro_bias_prior)}));
  problem.AddResidualBlock(costs.back().get(), nullptr, bg.data());
  costs.emplace_back(
      new ceres::AutoDiffCostFunction<BiasPrior, 3, 3>(new BiasPrior{std::sqrt(options.accel_bias_prior)}));
  problem.AddResidualBlock(costs.back().get(), nullptr, ba.data());
  if (!options.estimate_scale) problem.SetParameterBlockConstant(log_s.data());

  ceres::Solver::Options so;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  result.R_w_g = R_wg0 * so3_exp(Eigen::Vector3d(gdir[0], gdir[1], 0.0)).toRotationMatrix();
  result.gravity_w = result.R_w_g * Eigen::Vector3d(0.0, 0.0, -options.gravity);
  result.bias.gyro = bg;
  result.bias.accel = ba;
  result.scale = std::exp(log_s[0]);
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size());
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  return result;
}

}  // namespace orbatlas
