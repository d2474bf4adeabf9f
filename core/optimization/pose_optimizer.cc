#include "core/optimization/pose_optimizer.h"

#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <algorithm>
#include <memory>

#include "core/common/error.h"
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

  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  costs.reserve(n);
  for (const PoseCorrespondence& c : input.correspondences)
    costs.push_back(make_pose_only_cost(camera, c.p_w, {c.uv, c.u_right, c.level_sigma2}, input.bf));

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
      const std::optional<double> chi2 = residual_chi2(*costs[i], params);
      inlier[i] = chi2 && *chi2 <= chi2_threshold(i) ? 1 : 0;
    }
  };
  // Every correspondence starts as an inlier, unless it cannot be projected at all.
  for (std::size_t i = 0; i < n; ++i) inlier[i] = residual_chi2(*costs[i], params).has_value() ? 1 : 0;

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  const ceres::Solver::Options solver = solver_options(options.iterations_per_round);

  for (int round = 0; round < options.rounds; ++round) {
    const bool robust = round < options.robust_rounds;
    int in_problem = 0;
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(pose.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(pose.t.data(), 3);
    for (std::size_t i = 0; i < n; ++i) {
      if (!inlier[i]) continue;
      ceres::LossFunction* loss = nullptr;
      if (robust) loss = input.correspondences[i].u_right ? &huber_stereo : &huber_mono;
      problem.AddResidualBlock(costs[i].get(), loss, pose.q.data(), pose.t.data());
      ++in_problem;
    }
    if (in_problem < options.min_round_inliers) break;

    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    ++result.rounds;
    result.iterations += static_cast<int>(summary.iterations.size()) - 1;  // entry 0 is the start

    classify();  // at the new pose: outliers may come back
  }
  if (result.rounds == 0) classify();

  result.T_c_w = pose.pose();
  for (std::uint8_t f : inlier) result.inlier_count += f;
  return result;
}

}  // namespace orbatlas
