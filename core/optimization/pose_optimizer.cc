#include "core/optimization/pose_optimizer.h"

#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <memory>

#include "core/common/error.h"
#include "core/optimization/pose_levenberg.h"
#include "core/optimization/pose_parameters.h"
#include "core/optimization/reprojection_residuals.h"

namespace orbatlas {
namespace {

ceres::Solver::Options solver_options(int iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;  // 6 unknowns: the dense factorisation is trivial
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.max_num_iterations = iterations;
  o.num_threads = 1;
  o.minimizer_progress_to_stdout = false;
  o.logging_type = ceres::SILENT;
  o.function_tolerance = 1e-12;
  o.gradient_tolerance = 1e-14;
  o.parameter_tolerance = 1e-12;
  return o;
}

// The unknowns and costs of an inertial term (InertialPoseTerm).
struct InertialBlocks {
  explicit InertialBlocks(const InertialPoseTerm& term) : previous(PoseParameters::from_pose(term.previous_T_c_w)) {
    Eigen::Map<Eigen::Vector3d>(v.data()) = term.v_w;
    Eigen::Map<Eigen::Vector3d>(previous_v.data()) = term.previous_v_w;
    Eigen::Map<Eigen::Vector3d>(bias.data()) = term.bias.gyro;
    Eigen::Map<Eigen::Vector3d>(bias.data() + 3) = term.bias.accel;
    inertial = make_inertial_cost(term.increments, term.T_c_i, term.gravity_w);
    prior = make_state_prior(term.previous_T_c_w, term.previous_v_w, term.previous_covariance);
    Eigen::Matrix<double, 6, 1> bias_mean;
    bias_mean << term.bias.gyro, term.bias.accel;
    bias_prior = make_diagonal_prior(bias_mean, term.bias_sigma);
  }
  void add_to(ceres::Problem& problem, PoseParameters& pose, ceres::Manifold* quaternion) {
    problem.AddParameterBlock(previous.q.data(), 4, quaternion);
    problem.AddParameterBlock(previous.t.data(), 3);
    problem.AddResidualBlock(
        inertial.get(), nullptr,
        {previous.q.data(), previous.t.data(), previous_v.data(), pose.q.data(), pose.t.data(), v.data(), bias.data()});
    problem.AddResidualBlock(prior.get(), nullptr, previous.q.data(), previous.t.data(), previous_v.data());
    problem.AddResidualBlock(bias_prior.get(), nullptr, bias.data());
  }
  double chi2(const PoseParameters& pose) const {
    const double* params[7] = {previous.q.data(), previous.t.data(), previous_v.data(), pose.q.data(),
                               pose.t.data(),     v.data(),          bias.data()};
    Eigen::Matrix<double, 9, 1> r;
    if (!inertial->Evaluate(params, r.data(), nullptr)) return 0.0;
    return r.squaredNorm();
  }
  InertialPoseEstimate estimate(const PoseParameters& pose) const {
    InertialPoseEstimate e;
    e.v_w = Eigen::Map<const Eigen::Vector3d>(v.data());
    e.bias.gyro = Eigen::Map<const Eigen::Vector3d>(bias.data());
    e.bias.accel = Eigen::Map<const Eigen::Vector3d>(bias.data() + 3);
    e.chi2 = chi2(pose);
    return e;
  }

  PoseParameters previous;
  std::array<double, 3> v{}, previous_v{};
  std::array<double, 6> bias{};
  std::unique_ptr<ceres::CostFunction> inertial, prior, bias_prior;
};

// The marginal covariance of the frame's pose and velocity, in tangent
// coordinates: the inverse of the Gauss-Newton Hessian J^T J at the solution
// (the previous state and the biases marginalised out).
std::optional<StateCovariance> state_covariance(ceres::Problem& problem, PoseParameters& pose, InertialBlocks& blocks) {
  ceres::Problem::EvaluateOptions options;
  // The frame's blocks first: their tangent columns are 0..8.
  options.parameter_blocks = {pose.q.data(),
                              pose.t.data(),
                              blocks.v.data(),
                              blocks.previous.q.data(),
                              blocks.previous.t.data(),
                              blocks.previous_v.data(),
                              blocks.bias.data()};
  options.num_threads = 1;
  ceres::CRSMatrix J;
  if (!problem.Evaluate(options, nullptr, nullptr, nullptr, &J)) return std::nullopt;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(J.num_cols, J.num_cols);
  for (int r = 0; r < J.num_rows; ++r)
    for (int a = J.rows[r]; a < J.rows[r + 1]; ++a)
      for (int b = J.rows[r]; b < J.rows[r + 1]; ++b) H(J.cols[a], J.cols[b]) += J.values[a] * J.values[b];
  const Eigen::LLT<Eigen::MatrixXd> llt(H);
  if (llt.info() != Eigen::Success) return std::nullopt;
  const Eigen::MatrixXd covariance = llt.solve(Eigen::MatrixXd::Identity(J.num_cols, J.num_cols));
  const StateCovariance out = covariance.topLeftCorner<9, 9>();
  if (!out.allFinite()) return std::nullopt;
  return out;
}

}  // namespace

void PoseOptimizerOptions::check() const {
  ORBATLAS_CHECK(rounds >= 0, "pose optimisation: rounds must be >= 0, not " << rounds);
  ORBATLAS_CHECK(iterations_per_round >= 0,
                 "pose optimisation: iterations_per_round must be >= 0, not " << iterations_per_round);
  ORBATLAS_CHECK(robust_rounds >= 0, "pose optimisation: robust_rounds must be >= 0, not " << robust_rounds);
  ORBATLAS_CHECK(chi2_mono > 0.0, "pose optimisation: chi2_mono must be > 0, not " << chi2_mono);
  ORBATLAS_CHECK(chi2_stereo > 0.0, "pose optimisation: chi2_stereo must be > 0, not " << chi2_stereo);
  ORBATLAS_CHECK(huber_mono > 0.0, "pose optimisation: huber_mono must be > 0, not " << huber_mono);
  ORBATLAS_CHECK(huber_stereo > 0.0, "pose optimisation: huber_stereo must be > 0, not " << huber_stereo);
  ORBATLAS_CHECK(min_correspondences >= 0,
                 "pose optimisation: min_correspondences must be >= 0, not " << min_correspondences);
  ORBATLAS_CHECK(min_round_inliers >= 0,
                 "pose optimisation: min_round_inliers must be >= 0, not " << min_round_inliers);
}

PoseOptimizerResult optimize_pose(const Camera& camera, const PoseOptimizerInput& input,
                                  const PoseOptimizerOptions& options) {
  const std::size_t n = input.correspondences.size();
  PoseOptimizerResult result;
  result.T_c_w = input.T_c_w;
  result.inliers.assign(n, 0);
  if (n < static_cast<std::size_t>(std::max(options.min_correspondences, 1))) return result;

  PoseOnlyCosts costs(n);
  for (const PoseCorrespondence& c : input.correspondences)
    costs.add(camera, c.p_w, {c.uv, c.u_right, c.level_sigma2}, input.bf);

  PoseParameters pose = PoseParameters::from_pose(input.T_c_w);
  const double* params[2] = {pose.q.data(), pose.t.data()};
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::HuberLoss huber_mono(options.huber_mono), huber_stereo(options.huber_stereo);
  auto chi2_threshold = [&](std::size_t i) {
    return input.correspondences[i].u_right ? options.chi2_stereo : options.chi2_mono;
  };
  std::vector<std::uint8_t>& inlier = result.inliers;
  auto classify = [&] {
    for (std::size_t i = 0; i < n; ++i) {
      const std::optional<double> chi2 = residual_chi2(costs[i], params);
      inlier[i] = chi2 && *chi2 <= chi2_threshold(i) ? 1 : 0;
    }
  };
  // Every correspondence starts as an inlier, unless it cannot be projected at all.
  for (std::size_t i = 0; i < n; ++i) inlier[i] = residual_chi2(costs[i], params).has_value() ? 1 : 0;

  std::optional<InertialBlocks> inertial;
  if (input.inertial) inertial.emplace(*input.inertial);

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Solver::Options solver = solver_options(options.iterations_per_round);
  // With the inertial term the state is 26 values: the normal equations
  // (26 x 26) are cheaper to form and solve than a QR of the whole Jacobian.
  if (inertial) {
    solver.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
    solver.function_tolerance = 1e-8;  // the inertial weights are large: stop at 1e-8 of the cost, not 1e-12
  }

  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = round < options.robust_rounds;
    if (!inertial) {
      // The pose alone: Levenberg-Marquardt written out (pose_levenberg.h).
      std::vector<PoseTerm> terms;
      terms.reserve(n);
      for (std::size_t i = 0; i < n; ++i)
        if (inlier[i])
          terms.push_back({&costs[i], !robust                            ? 0.0
                                      : input.correspondences[i].u_right ? options.huber_stereo
                                                                         : options.huber_mono});
      if (static_cast<int>(terms.size()) < options.min_round_inliers) break;
      PoseLevenbergOptions lm;
      lm.max_iterations = options.iterations_per_round;
      const PoseLevenbergResult solved = solve_pose_levenberg(terms, pose, lm);
      ++result.rounds;
      result.iterations += solved.iterations;
      classify();  // at the new pose: outliers may come back
      continue;
    }
    int in_problem = 0;
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(pose.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(pose.t.data(), 3);
    for (std::size_t i = 0; i < n; ++i) {
      if (!inlier[i]) continue;
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = input.correspondences[i].u_right ? &huber_stereo : &huber_mono;
      problem.AddResidualBlock(&costs[i], loss, pose.q.data(), pose.t.data());
      ++in_problem;
    }
    if (in_problem < options.min_round_inliers) break;
    if (inertial) inertial->add_to(problem, pose, &quaternion_manifold);

    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    ++result.rounds;
    result.iterations += static_cast<int>(summary.iterations.size()) - 1;  // entry 0 is the start

    classify();  // at the new pose: outliers may come back
    if (inertial && round + 1 == options.rounds) {
      result.inertial = inertial->estimate(pose);
      result.inertial->covariance = state_covariance(problem, pose, *inertial);
    }
  }
  if (result.rounds == 0) classify();
  if (inertial && !result.inertial) result.inertial = inertial->estimate(pose);

  result.T_c_w = pose.pose();
  for (std::uint8_t f : inlier) result.inlier_count += f;
  return result;
}

}  // namespace orbatlas
