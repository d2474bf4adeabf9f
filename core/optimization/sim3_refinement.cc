#include "core/optimization/sim3_refinement.h"

#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <array>
#include <memory>
#include <optional>

#include "core/common/error.h"
#include "core/optimization/reprojection_residuals.h"
#include "core/optimization/sim3_costs.h"

namespace orbatlas {
namespace {

// S_1_2 as the three blocks of sim3_costs.h.
struct Sim3Parameters {
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};
  std::array<double, 3> t{0.0, 0.0, 0.0};
  std::array<double, 1> log_s{0.0};

  static Sim3Parameters from(const Sim3& S) {
    Sim3Parameters p;
    p.q = {S.q.x(), S.q.y(), S.q.z(), S.q.w()};
    p.t = {S.t.x(), S.t.y(), S.t.z()};
    p.log_s[0] = std::log(S.s);
    return p;
  }
  Sim3 sim3() const {
    return Sim3(Eigen::Map<const Eigen::Quaterniond>(q.data()), Eigen::Map<const Eigen::Vector3d>(t.data()),
                std::exp(log_s[0]));
  }
};

ceres::Solver::Options solver_options(int iterations) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;  // 7 unknowns
  o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  o.max_num_iterations = iterations;
  o.num_threads = 1;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  // Tight enough for noise-free data to converge to ~1e-9.
  o.function_tolerance = 1e-12;
  o.gradient_tolerance = 1e-14;
  o.parameter_tolerance = 1e-12;
  return o;
}

}  // namespace

void Sim3RefinementOptions::check() const {
  ORBATLAS_CHECK(chi2_threshold > 0.0, "Sim3 refinement: chi2_threshold must be > 0, not " << chi2_threshold);
  ORBATLAS_CHECK(first_iterations >= 0, "Sim3 refinement: first_iterations must be >= 0, not " << first_iterations);
  ORBATLAS_CHECK(second_iterations >= 0, "Sim3 refinement: second_iterations must be >= 0, not " << second_iterations);
  ORBATLAS_CHECK(second_iterations_clean >= 0,
                 "Sim3 refinement: second_iterations_clean must be >= 0, not " << second_iterations_clean);
  ORBATLAS_CHECK(min_inliers >= 0, "Sim3 refinement: min_inliers must be >= 0, not " << min_inliers);
}

Sim3RefinementResult refine_sim3(const Sim3& S_1_2_initial, const std::vector<Sim3Match>& matches,
                                 const Camera& camera1, const Camera& camera2, const Sim3RefinementOptions& options) {
  options.check();
  const std::size_t n = matches.size();
  Sim3RefinementResult result;
  result.S_1_2 = S_1_2_initial;
  result.inliers.assign(n, 0);

  // Two costs per match: [2i] forward into image 1, [2i+1] inverse into image 2.
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  costs.reserve(2 * n);
  for (const Sim3Match& m : matches) {
    costs.push_back(make_sim3_projection_cost(camera1, m.p_c2, m.uv1, m.level_sigma2_1, Sim3Projection::kForward));
    costs.push_back(make_sim3_projection_cost(camera2, m.p_c1, m.uv2, m.level_sigma2_2, Sim3Projection::kInverse));
  }
  if (n == 0 || static_cast<int>(n) < options.min_inliers) return result;

  Sim3Parameters S = Sim3Parameters::from(S_1_2_initial);
  const double* params[3] = {S.q.data(), S.t.data(), S.log_s.data()};
  auto fits = [&](std::size_t i) {
    for (std::size_t k = 2 * i; k < 2 * i + 2; ++k) {
      const std::optional<double> chi2 = residual_chi2(*costs[k], params);
      if (!chi2 || *chi2 > options.chi2_threshold) return false;
    }
    return true;
  };

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::HuberLoss huber(std::sqrt(options.chi2_threshold));

  // One pass over the matches flagged in `use`; returns the iterations run.
  auto run = [&](const std::vector<std::uint8_t>& use, int iterations, bool robust) {
    ceres::Problem problem(problem_options);
    problem.AddParameterBlock(S.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(S.t.data(), 3);
    problem.AddParameterBlock(S.log_s.data(), 1);
    if (options.fix_scale) problem.SetParameterBlockConstant(S.log_s.data());
    for (std::size_t i = 0; i < n; ++i) {
      if (!use[i]) continue;
      for (std::size_t k = 2 * i; k < 2 * i + 2; ++k)
        problem.AddResidualBlock(costs[k].get(), robust ? &huber : nullptr, S.q.data(), S.t.data(), S.log_s.data());
    }
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(iterations), &problem, &summary);
    return static_cast<int>(summary.iterations.size()) - 1;  // entry 0 is the start
  };

  // First pass on every match that can be evaluated at the start (a point behind
  // a camera would make every step fail).
  std::vector<std::uint8_t> use(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    use[i] = residual_chi2(*costs[2 * i], params) && residual_chi2(*costs[2 * i + 1], params) ? 1 : 0;
  result.iterations += run(use, options.first_iterations, true);

  int kept = 0, dropped = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!use[i]) continue;
    if (fits(i)) {
      ++kept;
    } else {
      use[i] = 0;
      ++dropped;
    }
  }
  if (kept < options.min_inliers) return result;

  const int second = dropped > 0 ? options.second_iterations : options.second_iterations_clean;
  result.iterations += run(use, second, options.robust_second_pass);

  result.success = true;
  result.S_1_2 = S.sim3();
  // Classified at the final estimate: a match dropped after the first pass that
  // fits the refined similarity counts as an inlier again.
  for (std::size_t i = 0; i < n; ++i) {
    result.inliers[i] = fits(i) ? 1 : 0;
    result.inlier_count += result.inliers[i];
  }
  return result;
}

}  // namespace orbatlas
