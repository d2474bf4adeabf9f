#include "core/optimization/local_bundle_adjustment.h"

#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <unordered_map>

#include "core/common/error.h"
#include "core/optimization/pose_parameters.h"
#include "core/optimization/reprojection_residuals.h"
#include "core/optimization/stop_flag_callback.h"

namespace orbatlas {
namespace {

struct Edge {
  std::size_t keyframe = 0;  // index into LocalProblem::keyframes
  std::size_t point = 0;     // index into LocalProblem::points
  std::size_t slot = 0;
  bool stereo = false;
  bool active = true;  // in the next stage's problem
  std::unique_ptr<ceres::CostFunction> cost;
};

// The window, the border, the points and their observations, with the Ceres
// parameter storage (never resized once built: Ceres keeps pointers into it).
struct LocalProblem {
  std::vector<std::shared_ptr<KeyFrame>> keyframes;  // window first, then the border
  std::vector<std::uint8_t> fixed;                   // per keyframe
  std::size_t window = 0;
  std::vector<PoseParameters> poses;  // T_c_w per keyframe
  std::vector<std::shared_ptr<MapPoint>> points;
  std::vector<std::array<double, 3>> positions;
  std::vector<Edge> edges;

  std::array<const double*, 3> parameters(const Edge& e) const {
    return {poses[e.keyframe].q.data(), poses[e.keyframe].t.data(), positions[e.point].data()};
  }
};

LocalProblem collect(const std::shared_ptr<KeyFrame>& current, const Camera& camera, double bf,
                     const LocalBundleAdjustmentOptions& options) {
  LocalProblem lp;
  std::unordered_map<KeyframeId, std::size_t> kf_index;
  auto add_keyframe = [&](std::shared_ptr<KeyFrame> kf) {
    if (kf_index.try_emplace(kf->id(), lp.keyframes.size()).second) lp.keyframes.push_back(std::move(kf));
  };
  add_keyframe(current);
  for (auto& kf : current->best_covisibles(options.max_covisibles)) add_keyframe(std::move(kf));
  lp.window = lp.keyframes.size();

  std::unordered_map<MapPointId, std::size_t> point_index;
  for (std::size_t k = 0; k < lp.window; ++k) {
    for (auto& mp : lp.keyframes[k]->map_points()) {
      if (mp->is_bad()) continue;
      if (point_index.try_emplace(mp->id(), lp.points.size()).second) lp.points.push_back(std::move(mp));
    }
  }

  // Observations; keyframes outside the window join the border.
  lp.positions.resize(lp.points.size());
  std::vector<PixelObservation> observations;  // per edge
  const bool use_stereo = bf > 0.0;
  for (std::size_t j = 0; j < lp.points.size(); ++j) {
    const Eigen::Vector3d p_w = lp.points[j]->p_w();
    std::copy(p_w.data(), p_w.data() + 3, lp.positions[j].begin());
    for (const MapPointObservation& obs : lp.points[j]->observations()) {
      std::shared_ptr<KeyFrame> kf = obs.kf.lock();
      if (!kf || kf->is_bad()) continue;
      const Keypoint& kp = kf->keypoint(obs.slot);
      ORBATLAS_CHECK(kp.level >= 0 && static_cast<std::size_t>(kp.level) < options.level_sigma2.size(),
                     "local bundle adjustment: keyframe " << kf->id() << " slot " << obs.slot << " has level "
                                                          << kp.level << " without a sigma2");
      PixelObservation px{kp.uv.cast<double>(), std::nullopt, options.level_sigma2[static_cast<std::size_t>(kp.level)]};
      if (use_stereo && kf->is_stereo() && kf->u_right(obs.slot) >= 0.0f) px.u_right = kf->u_right(obs.slot);
      add_keyframe(kf);
      Edge e;
      e.keyframe = kf_index.at(kf->id());
      e.point = j;
      e.slot = obs.slot;
      e.stereo = px.u_right.has_value();
      observations.push_back(px);
      lp.edges.push_back(std::move(e));
    }
  }
  // With stereo present, monocular rows are padded to 3 so every row block has
  // one size (Ceres' fixed-size Schur eliminator instead of the dynamic one).
  const bool pad_mono = std::any_of(lp.edges.begin(), lp.edges.end(), [](const Edge& e) { return e.stereo; });
  for (std::size_t i = 0; i < lp.edges.size(); ++i)
    lp.edges[i].cost = make_pose_point_cost(camera, observations[i], bf, pad_mono);

  lp.fixed.assign(lp.keyframes.size(), 0);
  std::fill(lp.fixed.begin() + static_cast<std::ptrdiff_t>(lp.window), lp.fixed.end(), 1);
  for (std::size_t k = 0; k < lp.window; ++k)
    if (options.origin && lp.keyframes[k]->id() == *options.origin) lp.fixed[k] = 1;
  if (options.fix_oldest_without_border && std::find(lp.fixed.begin(), lp.fixed.end(), 1) == lp.fixed.end()) {
    std::size_t oldest = 0;
    for (std::size_t k = 1; k < lp.window; ++k)
      if (lp.keyframes[k]->id() < lp.keyframes[oldest]->id()) oldest = k;
    lp.fixed[oldest] = 1;
  }
  lp.poses.reserve(lp.keyframes.size());
  for (const auto& kf : lp.keyframes) lp.poses.push_back(PoseParameters::from_pose(kf->T_w_c().inverse()));
  return lp;
}

// Chi2 of an edge at the current estimates, nullopt when the point is behind the
// camera or cannot be projected.
std::optional<double> edge_chi2(const LocalProblem& lp, const Edge& e) {
  const std::array<const double*, 3> params = lp.parameters(e);
  double p_c[3];
  world_to_camera(params[0], params[1], params[2], p_c);
  if (!(p_c[2] > 0.0)) return std::nullopt;
  return residual_chi2(*e.cost, params.data());
}

bool is_outlier(const LocalProblem& lp, const Edge& e, const LocalBundleAdjustmentOptions& options) {
  const std::optional<double> chi2 = edge_chi2(lp, e);
  return !chi2 || *chi2 > (e.stereo ? options.chi2_stereo : options.chi2_mono);
}

// One stage: a problem over the active edges, solved for `iterations`.
ceres::Solver::Summary solve_stage(LocalProblem& lp, bool robust, int iterations,
                                   const LocalBundleAdjustmentOptions& options, StopFlagCallback& callback) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::HuberLoss huber_mono(options.huber_mono), huber_stereo(options.huber_stereo);

  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  std::vector<std::uint8_t> pose_added(lp.keyframes.size(), 0), point_added(lp.points.size(), 0);
  std::size_t free_keyframes = 0;
  for (Edge& e : lp.edges) {
    if (!e.active) continue;
    PoseParameters& pose = lp.poses[e.keyframe];
    double* p = lp.positions[e.point].data();
    if (!pose_added[e.keyframe]) {
      pose_added[e.keyframe] = 1;
      problem.AddParameterBlock(pose.q.data(), 4, &quaternion_manifold);
      problem.AddParameterBlock(pose.t.data(), 3);
      ordering->AddElementToGroup(pose.q.data(), 1);
      ordering->AddElementToGroup(pose.t.data(), 1);
      if (lp.fixed[e.keyframe]) {
        problem.SetParameterBlockConstant(pose.q.data());
        problem.SetParameterBlockConstant(pose.t.data());
      } else {
        ++free_keyframes;
      }
    }
    if (!point_added[e.point]) {
      point_added[e.point] = 1;
      problem.AddParameterBlock(p, 3);
      ordering->AddElementToGroup(p, 0);  // points first: eliminated by the Schur complement
    }
    ceres::LossFunction* loss = nullptr;
    if (robust) loss = e.stereo ? &huber_stereo : &huber_mono;
    problem.AddResidualBlock(e.cost.get(), loss, pose.q.data(), pose.t.data(), p);
  }

  ceres::Solver::Summary summary;
  if (problem.NumResidualBlocks() == 0) return summary;
  ceres::Solver::Options so;
  const bool sparse = free_keyframes > options.dense_schur_max_keyframes &&
                      ceres::IsSparseLinearAlgebraLibraryTypeAvailable(so.sparse_linear_algebra_library_type);
  so.linear_solver_type = sparse ? ceres::SPARSE_SCHUR : ceres::DENSE_SCHUR;
  so.linear_solver_ordering = ordering;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = iterations;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.callbacks.push_back(&callback);  // not owned
  ceres::Solve(so, &problem, &summary);
  return summary;
}

void write_back(const LocalProblem& lp) {
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

LocalBundleAdjustmentStats local_bundle_adjustment(Map& map, const std::shared_ptr<KeyFrame>& current,
                                                   const Camera& camera, double bf,
                                                   const LocalBundleAdjustmentOptions& options,
                                                   const std::atomic<bool>* stop) {
  ORBATLAS_CHECK(current != nullptr, "local bundle adjustment: no current keyframe");
  const auto start = std::chrono::steady_clock::now();
  LocalBundleAdjustmentStats stats;
  if (current->is_bad()) return stats;

  LocalProblem lp = collect(current, camera, bf, options);
  for (std::size_t k = 0; k < lp.keyframes.size(); ++k) (lp.fixed[k] ? stats.fixed_keyframes : stats.window_keyframes)++;
  stats.points = lp.points.size();
  stats.observations = lp.edges.size();

  StopFlagCallback callback(stop);
  stats.iterations += std::max(0, static_cast<int>(solve_stage(lp, true, options.first_iterations, options, callback)
                                                       .iterations.size()) - 1);
  stats.stopped = callback.stopped();
  if (!stats.stopped && options.second_iterations > 0) {
    for (Edge& e : lp.edges) e.active = !is_outlier(lp, e, options);
    stats.iterations += std::max(0, static_cast<int>(solve_stage(lp, false, options.second_iterations, options,
                                                                 callback).iterations.size()) - 1);
    stats.stopped = callback.stopped();
  }

  if (!stats.stopped) {
    // Erase the observations that do not fit (both sides), then the points left
    // with too few observers.
    std::vector<std::uint8_t> touched(lp.points.size(), 0);
    for (const Edge& e : lp.edges) {
      if (!is_outlier(lp, e, options)) continue;
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
  stats.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace orbatlas
