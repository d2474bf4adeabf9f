#include "core/common/stopwatch.h"
#include "core/optimization/global_bundle_adjustment.h"

#include <algorithm>
#include <chrono>
#include <unordered_set>

#include "core/common/error.h"
#include "core/map/inertial_chain.h"
#include "core/optimization/bundle_problem.h"
#include "core/optimization/inertial_window.h"

namespace orbatlas {

void GlobalBundleAdjustmentOptions::check() const {
  ORBATLAS_CHECK(iterations >= 0, "global BA: iterations must be >= 0, not " << iterations);
  ORBATLAS_CHECK(huber_mono > 0.0, "global BA: huber_mono must be > 0, not " << huber_mono);
  ORBATLAS_CHECK(huber_stereo > 0.0, "global BA: huber_stereo must be > 0, not " << huber_stereo);
  check_level_sigma2(level_sigma2, "global BA");
  ORBATLAS_CHECK(num_threads >= 1, "global BA: num_threads must be >= 1, not " << num_threads);
  if (inertial) {
    ORBATLAS_CHECK(inertial->max_chain_keyframes >= 2,
                   "global BA: max_chain_keyframes must be >= 2, not " << inertial->max_chain_keyframes);
    ORBATLAS_CHECK(inertial->huber >= 0.0, "global BA: the inertial Huber width must be >= 0, not " << inertial->huber);
  }
}

namespace {

// Every inertial chain of the map (one per visual-inertial session that mapped
// in it: a merge joins the sessions' maps, not their chains), newest first, each
// the newest `max_keyframes` of its chain. Keyframe ids grow with time, so the
// newest keyframe of a chain is met before the others.
std::vector<InertialChainWindow> inertial_chains(const std::vector<std::shared_ptr<KeyFrame>>& keyframes,
                                                 std::size_t max_keyframes) {
  std::vector<InertialChainWindow> chains;
  std::unordered_set<const KeyFrame*> covered;
  for (auto it = keyframes.rbegin(); it != keyframes.rend(); ++it) {
    if ((*it)->is_bad() || !(*it)->inertial_link() || covered.count(it->get())) continue;
    std::vector<std::shared_ptr<KeyFrame>> chain = inertial_chain(*it);
    for (const auto& kf : chain) covered.insert(kf.get());
    if (chain.size() > max_keyframes)
      chain.erase(chain.begin(), chain.begin() + static_cast<std::ptrdiff_t>(chain.size() - max_keyframes));
    if (chain.size() >= 2) chains.push_back(InertialChainWindow{std::move(chain), false});
  }
  return chains;
}

}  // namespace

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
  const auto inertial_state = options.inertial ? map.inertial_state() : std::nullopt;
  std::vector<InertialWindow> windows;
  InertialWindowOptions window_options;
  if (inertial_state) {
    const std::vector<InertialChainWindow> chains = inertial_chains(keyframes, options.inertial->max_chain_keyframes);
    window_options.T_b_i = options.inertial->T_b_i;
    window_options.gravity_w = inertial_state->gravity_w;
    window_options.map_bias = inertial_state->bias;
    window_options.scale = inertial_state->scale;  // held: local BA estimates it
    // Every chain keyframe indexed before any term points into the poses.
    for (const auto& chain : chains)
      for (const auto& kf : chain.keyframes) bundle_keyframe_index(problem, kf);
    for (const auto& chain : chains) {
      window_options.temporal_keyframes = chain.keyframes.size();
      windows.push_back(add_inertial_window(problem, chain, window_options));
      for (const std::size_t t : windows.back().inertial_terms) problem.extra_terms[t].huber = options.inertial->huber;
    }
  }

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
  result.iterations = solve_bundle_stage(problem, true, options.iterations, settings, callback);
  result.stopped = callback.stopped();

  for (std::size_t k = 0; k < problem.window; ++k) {
    const KeyFrame& kf = *problem.keyframes[k];
    result.T_w_b[kf.id()] = problem.poses[k].pose().inverse() * kf.T_b_c().inverse();
  }
  for (std::size_t j = 0; j < problem.points.size(); ++j)
    result.p_w[problem.points[j]->id()] =
        Eigen::Vector3d(problem.positions[j][0], problem.positions[j][1], problem.positions[j][2]);
  for (const InertialWindow& window : windows) {
    for (const auto& [kf, state] : inertial_window_states(problem, window, window_options))
      result.imu_states[kf->id()] = state;
    result.inertial_keyframes += window.index.size();
    result.inertial_edges += window.inertial_terms.size();
    for (const double chi2 : inertial_window_chi2(problem, window))
      result.inertial_chi2_max = std::max(result.inertial_chi2_max, chi2);
  }
  result.inertial_chains = windows.size();
  result.keyframes = problem.window;
  result.points = problem.points.size();
  result.observations = problem.edges.size();
  result.time_ms = ms_since(start);
  return result;
}

}  // namespace orbatlas
