#include "core/common/stopwatch.h"
#include "core/optimization/global_bundle_adjustment.h"

#include <algorithm>
#include <chrono>

#include "core/common/error.h"
#include "core/optimization/bundle_problem.h"

namespace orbatlas {

void GlobalBundleAdjustmentOptions::check() const {
  ORBATLAS_CHECK(iterations >= 0, "global BA: iterations must be >= 0, not " << iterations);
  ORBATLAS_CHECK(huber_mono > 0.0, "global BA: huber_mono must be > 0, not " << huber_mono);
  ORBATLAS_CHECK(huber_stereo > 0.0, "global BA: huber_stereo must be > 0, not " << huber_stereo);
  check_level_sigma2(level_sigma2, "global BA");
  ORBATLAS_CHECK(num_threads >= 1, "global BA: num_threads must be >= 1, not " << num_threads);
}

GlobalBundleAdjustmentResult global_bundle_adjustment(const Map& map, const Camera& camera, double bf,
                                                      const GlobalBundleAdjustmentOptions& options,
                                                      const std::atomic<bool>* stop) {
  options.check();
  const auto start = std::chrono::steady_clock::now();
  GlobalBundleAdjustmentResult result;
  result.frame_epoch = map.frame_epoch();  // before the snapshot: a change after it drops the result
  const auto keyframes = map.keyframes();
  if (keyframes.size() < 2) return result;

  BundleSettings settings;
  settings.huber_mono = options.huber_mono;
  settings.huber_stereo = options.huber_stereo;
  settings.chi2_mono = options.huber_mono * options.huber_mono;
  settings.chi2_stereo = options.huber_stereo * options.huber_stereo;
  settings.level_sigma2 = options.level_sigma2;
  settings.num_threads = options.num_threads;
  settings.dense_schur_max_keyframes = 40;
  BundleProblem problem = collect_bundle_problem(keyframes, camera, bf, settings);

  // Gauge: the origin, else the oldest keyframe (keyframes() is sorted by id).
  std::size_t gauge = 0;
  for (std::size_t k = 0; k < problem.window; ++k)
    if (options.origin && problem.keyframes[k]->id() == *options.origin) gauge = k;
  if (problem.window > 0) problem.fixed[gauge] = 1;

  // Poses the solve starts from (collect read them; re-read the same snapshot).
  for (std::size_t k = 0; k < problem.keyframes.size(); ++k) {
    const KeyFrame& kf = *problem.keyframes[k];
    result.T_w_b_before[kf.id()] = problem.poses[k].pose().inverse() * kf.T_b_c().inverse();
  }

  StopFlagCallback callback(stop);
  const ceres::Solver::Summary summary = solve_bundle_stage(problem, true, options.iterations, settings, callback);
  result.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  result.stopped = callback.stopped();

  for (std::size_t k = 0; k < problem.window; ++k) {
    const KeyFrame& kf = *problem.keyframes[k];
    result.T_w_b[kf.id()] = problem.poses[k].pose().inverse() * kf.T_b_c().inverse();
  }
  for (std::size_t j = 0; j < problem.points.size(); ++j)
    result.p_w[problem.points[j]->id()] =
        Eigen::Vector3d(problem.positions[j][0], problem.positions[j][1], problem.positions[j][2]);
  result.keyframes = problem.window;
  result.points = problem.points.size();
  result.observations = problem.edges.size();
  result.time_ms = ms_since(start);
  return result;
}

}  // namespace orbatlas
