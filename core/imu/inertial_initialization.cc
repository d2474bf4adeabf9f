#include "core/imu/inertial_initialization.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <cmath>
#include <limits>
#include <memory>

#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "core/imu/inertial_residual.h"

namespace orbatlas {
namespace {

// The inertial residual between keyframes i and j (Preintegration::residual),
// whitened by the preintegration's information, as a function of both
// velocities, the window's biases, the gravity direction and the log scale.
struct InertialEdge {
  const Preintegration* increments = nullptr;          // not owned
  Eigen::Matrix3d Ri, Rj;                              // IMU rotations (fixed)
  Eigen::Vector3d pi_body, pj_body, lever_i, lever_j;  // IMU position = s * p_body + lever
  Eigen::Matrix<double, 9, 9> weight;                  // whitening of the increments
  Eigen::Matrix3d R_wg0;
  double gravity = 9.81;

  template <typename T>
  bool operator()(const T* vi_, const T* vj_, const T* bg_, const T* ba_, const T* gdir_, const T* log_s_,
                  T* out) const {
    const auto vec = [](const T* x) { return Vec3T<T>(x[0], x[1], x[2]); };
    const Vec3T<T> vi = vec(vi_), vj = vec(vj_), bg = vec(bg_), ba = vec(ba_);
    const Vec3T<T> tilt(gdir_[0], gdir_[1], T(0));
    const Vec3T<T> g = R_wg0.cast<T>() * so3_exp_t<T>(tilt) * Vec3T<T>(T(0), T(0), T(-gravity));
    const T s = ceres::exp(log_s_[0]);
    const Vec3T<T> pi = s * pi_body.cast<T>() + lever_i.cast<T>();
    const Vec3T<T> pj = s * pj_body.cast<T>() + lever_j.cast<T>();
    Eigen::Map<Eigen::Matrix<T, 9, 1>> whitened(out);
    whitened =
        weight.cast<T>() * inertial_residual<T>(*increments, Ri.cast<T>(), pi, vi, Rj.cast<T>(), pj, vj, bg, ba, g);
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
  ORBATLAS_CHECK(std::isfinite(visual_rotation_sigma) && visual_rotation_sigma >= 0.0 &&
                     std::isfinite(visual_position_sigma) && visual_position_sigma >= 0.0,
                 "inertial init: the visual sigmas must be >= 0");
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
  std::vector<ceres::ResidualBlockId> links;
  std::vector<Eigen::Matrix<double, 9, 9>> weights;
  for (std::size_t k = 0; k + 1 < n; ++k) {
    const Preintegration& pre = preintegrated[k];
    ORBATLAS_CHECK(pre.bias() == bias0, "inertial init: the preintegrations must share one bias");
    auto edge = std::make_unique<InertialEdge>();
    edge->increments = &pre;
    edge->Ri = R[k];
    edge->Rj = R[k + 1];
    edge->pi_body = T_w_b[k].t;
    edge->pj_body = T_w_b[k + 1].t;
    edge->lever_i = lever[k];
    edge->lever_j = lever[k + 1];
    edge->weight = whitening<9>(pre.covariance());
    weights.push_back(edge->weight);
    edge->R_wg0 = R_wg0;
    edge->gravity = options.gravity;
    costs.push_back(std::make_unique<ceres::AutoDiffCostFunction<InertialEdge, 9, 3, 3, 3, 3, 2, 1>>(
        edge.release()));  // the cost owns its functor
    links.push_back(problem.AddResidualBlock(costs.back().get(), nullptr, result.velocities[k].data(),
                                             result.velocities[k + 1].data(), bg.data(), ba.data(), gdir.data(),
                                             log_s.data()));
  }
  costs.push_back(std::make_unique<ceres::AutoDiffCostFunction<BiasPrior, 3, 3>>(
      std::make_unique<BiasPrior>(BiasPrior{std::sqrt(options.gyro_bias_prior)}).release()));
  problem.AddResidualBlock(costs.back().get(), nullptr, bg.data());
  costs.push_back(std::make_unique<ceres::AutoDiffCostFunction<BiasPrior, 3, 3>>(
      std::make_unique<BiasPrior>(BiasPrior{std::sqrt(options.accel_bias_prior)}).release()));
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
  for (std::size_t k = 0; k < links.size(); ++k) {
    Eigen::Matrix<double, 9, 1> whitened;
    if (!problem.EvaluateResidualBlock(links[k], false, nullptr, whitened.data(), nullptr)) {
      result.link_chi2.push_back(std::numeric_limits<double>::infinity());
      result.link_rotation_chi2.push_back(std::numeric_limits<double>::infinity());
      continue;
    }
    // The raw residual back from the whitened one, under the increments'
    // covariance and the two keyframe poses' error.
    const Eigen::Matrix<double, 9, 1> r = weights[k].lu().solve(whitened);
    Eigen::Matrix<double, 9, 9> cov = preintegrated[k].covariance();
    cov.diagonal().head<3>().array() += 2.0 * options.visual_rotation_sigma * options.visual_rotation_sigma;
    cov.diagonal().tail<3>().array() += 2.0 * options.visual_position_sigma * options.visual_position_sigma;
    result.link_chi2.push_back(r.dot(cov.ldlt().solve(r)));
    const Eigen::Matrix3d rotation_cov = cov.topLeftCorner<3, 3>();
    result.link_rotation_chi2.push_back(r.head<3>().dot(rotation_cov.ldlt().solve(r.head<3>())));
  }
  return result;
}

}  // namespace orbatlas
