#include "core/common/stopwatch.h"
#include "core/optimization/local_bundle_adjustment.h"

#include <algorithm>
#include <chrono>

#include "core/common/error.h"
#include "core/optimization/bundle_problem.h"

namespace orbatlas {
namespace {

BundleSettings settings_of(const LocalBundleAdjustmentOptions& o) {
  BundleSettings s;
  s.chi2_mono = o.chi2_mono;
  s.chi2_stereo = o.chi2_stereo;
  s.huber_mono = o.huber_mono;
  s.huber_stereo = o.huber_stereo;
  s.level_sigma2 = o.level_sigma2;
  s.dense_schur_max_keyframes = o.dense_schur_max_keyframes;
  s.own_solver = o.own_solver;
  s.num_threads = o.num_threads;
  return s;
}

void fix_gauge(BundleProblem& lp, const LocalBundleAdjustmentOptions& options) {
  for (std::size_t k = 0; k < lp.window; ++k)
    if (options.origin && lp.keyframes[k]->id() == *options.origin) lp.fixed[k] = 1;
  if (options.fix_oldest_without_border && std::find(lp.fixed.begin(), lp.fixed.end(), 1) == lp.fixed.end()) {
    std::size_t oldest = 0;
    for (std::size_t k = 1; k < lp.window; ++k)
      if (lp.keyframes[k]->id() < lp.keyframes[oldest]->id()) oldest = k;
    lp.fixed[oldest] = 1;
  }
}

void write_back(const BundleProblem& lp) {
  for (std::size_t k = 0; k < lp.keyframes.size(); ++k) {
    KeyFrame& kf = *lp.keyframes[k];
    if (lp.fixed[k] || kf.is_bad()) continue;
    kf.set_T_w_b(lp.poses[k].pose().inverse() * kf.T_b_c().inverse());  // T_w_c * T_c_b
  }
  for (std::size_t j = 0; j < lp.points.size(); ++j) {
    if (lp.points[j]->is_bad()) continue;
    lp.points[j]->set_p_w(Eigen::Vector3d(lp.positions[j][0], lp.positions[j][1], lp.positions[j][2]));
  }
}

}  // namespace

void LocalBundleAdjustmentOptions::check() const {
  ORBATLAS_CHECK(first_iterations >= 0, "local BA: first_iterations must be >= 0, not " << first_iterations);
  ORBATLAS_CHECK(second_iterations >= 0, "local BA: second_iterations must be >= 0, not " << second_iterations);
  ORBATLAS_CHECK(chi2_mono > 0.0, "local BA: chi2_mono must be > 0, not " << chi2_mono);
  ORBATLAS_CHECK(chi2_stereo > 0.0, "local BA: chi2_stereo must be > 0, not " << chi2_stereo);
  ORBATLAS_CHECK(huber_mono > 0.0, "local BA: huber_mono must be > 0, not " << huber_mono);
  ORBATLAS_CHECK(huber_stereo > 0.0, "local BA: huber_stereo must be > 0, not " << huber_stereo);
  check_level_sigma2(level_sigma2, "local BA");
  if (inertial) inertial->check();
  ORBATLAS_CHECK(num_threads >= 1, "local BA: num_threads must be >= 1, not " << num_threads);
}

LocalBundleAdjustmentStats local_bundle_adjustment(Map& map, const std::shared_ptr<KeyFrame>& current,
                                                   const Camera& camera, double bf,
                                                   const LocalBundleAdjustmentOptions& options,
                                                   const std::atomic<bool>* stop) {
  ORBATLAS_CHECK(current != nullptr, "local bundle adjustment: no current keyframe");
  const auto start = std::chrono::steady_clock::now();
  LocalBundleAdjustmentStats stats;
  if (current->is_bad()) return stats;

  const BundleSettings settings = settings_of(options);
  std::vector<std::shared_ptr<KeyFrame>> window{current};
  InertialChainWindow chain;
  if (options.inertial) {
    chain = inertial_chain_window(current, *options.inertial);
    for (std::size_t i = chain.anchored ? 1 : 0; i < chain.keyframes.size(); ++i)
      if (chain.keyframes[i] != current) window.push_back(chain.keyframes[i]);
  }
  for (auto& kf : current->best_covisibles(options.max_covisibles))
    if (!chain.anchored || kf != chain.keyframes.front()) window.push_back(std::move(kf));
  BundleProblem lp = collect_bundle_problem(window, camera, bf, settings);
  InertialWindow inertial;
  if (options.inertial) inertial = add_inertial_window(lp, chain, *options.inertial);
  fix_gauge(lp, options);
  stats.inertial_keyframes = inertial.index.size();
  stats.inertial_edges = inertial.inertial_terms.size();
  for (std::size_t k = 0; k < lp.keyframes.size(); ++k)
    (lp.fixed[k] ? stats.fixed_keyframes : stats.window_keyframes)++;
  stats.points = lp.points.size();
  stats.observations = lp.edges.size();

  StopFlagCallback callback(stop);
  stats.iterations += solve_bundle_stage(lp, true, options.first_iterations, settings, callback);
  stats.stopped = callback.stopped();
  if (!stats.stopped && options.second_iterations > 0) {
    for (BundleEdge& e : lp.edges) e.active = !is_bundle_outlier(lp, e, settings);
    stats.iterations += solve_bundle_stage(lp, false, options.second_iterations, settings, callback);
    stats.stopped = callback.stopped();
  }

  if (!stats.stopped) {
    // Erase the observations that do not fit (both sides), then the points left
    // with too few observers.
    std::vector<std::uint8_t> touched(lp.points.size(), 0);
    for (const BundleEdge& e : lp.edges) {
      if (!is_bundle_outlier(lp, e, settings)) continue;
      const std::shared_ptr<KeyFrame>& kf = lp.keyframes[e.keyframe];
      if (kf->map_point(e.slot) != lp.points[e.point]) continue;  // changed meanwhile
      if (kf->erase_slot(e.slot)) ++stats.observations_removed;
      touched[e.point] = 1;
    }
    for (std::size_t j = 0; j < lp.points.size(); ++j) {
      if (!touched[j] || lp.points[j]->is_bad()) continue;
      if (lp.points[j]->observation_count() < options.min_observers && map.cull_map_point(lp.points[j]->id()))
        ++stats.points_culled;
    }
  }
  write_back(lp);
  if (options.inertial) {
    write_back_inertial_window(lp, inertial, *options.inertial);
    stats.imu_scale = inertial_window_scale(lp, inertial, *options.inertial);
    stats.imu_scale_information = inertial_window_scale_information(lp, inertial);
    std::vector<double> chi2 = inertial_window_chi2(lp, inertial);
    for (const double c : chi2) stats.inertial_chi2_max = std::max(stats.inertial_chi2_max, c);
    if (!chi2.empty()) {
      std::nth_element(chi2.begin(), chi2.begin() + static_cast<std::ptrdiff_t>(chi2.size() / 2), chi2.end());
      stats.inertial_chi2_median = chi2[chi2.size() / 2];
    }
  }
  stats.time_ms = ms_since(start);
  return stats;
}

}  // namespace orbatlas
