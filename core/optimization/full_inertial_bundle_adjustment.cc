#include "core/optimization/full_inertial_bundle_adjustment.h"

#include <algorithm>
#include <chrono>

#include "core/common/error.h"
#include "core/common/stopwatch.h"
#include "core/map/inertial_chain.h"
#include "core/optimization/bundle_problem.h"

namespace orbatlas {

void FullInertialBundleAdjustmentOptions::check() const {
  ORBATLAS_CHECK(iterations >= 0, "full visual-inertial BA: iterations must be >= 0, not " << iterations);
  ORBATLAS_CHECK(huber_mono > 0.0, "full visual-inertial BA: huber_mono must be > 0, not " << huber_mono);
  ORBATLAS_CHECK(huber_stereo > 0.0, "full visual-inertial BA: huber_stereo must be > 0, not " << huber_stereo);
  check_level_sigma2(level_sigma2, "full visual-inertial BA");
  ORBATLAS_CHECK(max_chain_keyframes >= 2,
                 "full visual-inertial BA: max_chain_keyframes must be >= 2, not " << max_chain_keyframes);
  ORBATLAS_CHECK(num_threads >= 1, "full visual-inertial BA: num_threads must be >= 1, not " << num_threads);
}

FullInertialBundleAdjustmentStats full_inertial_bundle_adjustment(Map& map, const std::shared_ptr<KeyFrame>& newest,
                                                                  const Camera& camera, double bf,
                                                                  const FullInertialBundleAdjustmentOptions& options,
                                                                  const std::atomic<bool>* stop) {
  options.check();
  ORBATLAS_CHECK(newest != nullptr, "full visual-inertial BA: no newest keyframe");
  const auto start = std::chrono::steady_clock::now();
  FullInertialBundleAdjustmentStats stats;
  InertialChainWindow chain;
  chain.keyframes = inertial_chain(newest, options.max_chain_keyframes);
  chain.anchored = false;
  const auto keyframes = map.keyframes();
  if (chain.keyframes.size() < 2 || keyframes.size() < 2) return stats;

  BundleSettings settings;
  settings.huber_mono = options.huber_mono;
  settings.huber_stereo = options.huber_stereo;
  settings.chi2_mono = options.huber_mono * options.huber_mono;
  settings.chi2_stereo = options.huber_stereo * options.huber_stereo;
  settings.level_sigma2 = options.level_sigma2;
  settings.num_threads = options.num_threads;
  settings.dense_schur_max_keyframes = 40;
  BundleProblem problem = collect_bundle_problem(keyframes, camera, bf, settings);
  InertialWindowOptions inertial = options.inertial;
  inertial.temporal_keyframes = chain.keyframes.size();
  const InertialWindow window = add_inertial_window(problem, chain, inertial);
  // Gauge: the chain's oldest keyframe (gravity fixes roll and pitch; the
  // fixed pose the yaw and the position).
  if (!window.index.empty()) problem.fixed[window.index.front()] = 1;

  StopFlagCallback callback(stop);
  const ceres::Solver::Summary summary = solve_bundle_stage(problem, true, options.iterations, settings, callback);
  stats.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  stats.stopped = callback.stopped();
  stats.keyframes = problem.window;
  stats.points = problem.points.size();
  stats.observations = problem.edges.size();
  stats.inertial_keyframes = window.index.size();
  stats.inertial_edges = window.inertial_terms.size();
  if (stats.stopped) {
    stats.time_ms = ms_since(start);
    return stats;
  }
  for (std::size_t k = 0; k < problem.window; ++k) {
    KeyFrame& kf = *problem.keyframes[k];
    if (problem.fixed[k] || kf.is_bad()) continue;
    kf.set_T_w_b(problem.poses[k].pose().inverse() * kf.T_b_c().inverse());  // T_w_c * T_c_b
  }
  for (std::size_t j = 0; j < problem.points.size(); ++j) {
    if (problem.points[j]->is_bad()) continue;
    problem.points[j]->set_p_w(
        Eigen::Vector3d(problem.positions[j][0], problem.positions[j][1], problem.positions[j][2]));
  }
  write_back_inertial_window(problem, window, inertial);
  for (const double chi2 : inertial_window_chi2(problem, window))
    stats.inertial_chi2_max = std::max(stats.inertial_chi2_max, chi2);
  stats.time_ms = ms_since(start);
  return stats;
}

}  // namespace orbatlas
