#include "core/optimization/bundle_problem.h"

#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>

#include <algorithm>
#include <unordered_map>

#include "core/common/error.h"
#include "core/optimization/bundle_levenberg.h"
#include "core/optimization/reprojection_residuals.h"

namespace orbatlas {

BundleProblem collect_bundle_problem(const std::vector<std::shared_ptr<KeyFrame>>& window, const Camera& camera,
                                     double bf, const BundleSettings& options) {
  BundleProblem lp;
  std::unordered_map<KeyframeId, std::size_t> kf_index;
  auto add_keyframe = [&](std::shared_ptr<KeyFrame> kf) {
    if (kf_index.try_emplace(kf->id(), lp.keyframes.size()).second) lp.keyframes.push_back(std::move(kf));
  };
  for (const auto& kf : window)
    if (kf && !kf->is_bad()) add_keyframe(kf);
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
                     "bundle adjustment: keyframe " << kf->id() << " slot " << obs.slot << " has level " << kp.level
                                                    << " without a sigma2");
      PixelObservation px{kp.uv.cast<double>(), std::nullopt, options.level_sigma2[static_cast<std::size_t>(kp.level)]};
      if (use_stereo && kf->is_stereo() && kf->u_right(obs.slot) >= 0.0f) px.u_right = kf->u_right(obs.slot);
      add_keyframe(kf);
      BundleEdge e;
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
  const bool pad_mono = std::any_of(lp.edges.begin(), lp.edges.end(), [](const BundleEdge& e) { return e.stereo; });
  for (std::size_t i = 0; i < lp.edges.size(); ++i)
    lp.edges[i].cost = make_pose_point_cost(camera, observations[i], bf, pad_mono);

  lp.fixed.assign(lp.keyframes.size(), 0);
  std::fill(lp.fixed.begin() + static_cast<std::ptrdiff_t>(lp.window), lp.fixed.end(), 1);
  lp.poses.reserve(lp.keyframes.size());
  for (const auto& kf : lp.keyframes) lp.poses.push_back(PoseParameters::from_pose(kf->T_w_c().inverse()));
  return lp;
}

std::size_t bundle_keyframe_index(BundleProblem& lp, const std::shared_ptr<KeyFrame>& kf) {
  for (std::size_t k = 0; k < lp.keyframes.size(); ++k)
    if (lp.keyframes[k] == kf) return k;
  lp.keyframes.push_back(kf);
  lp.fixed.push_back(1);
  lp.poses.push_back(PoseParameters::from_pose(kf->T_w_c().inverse()));
  return lp.keyframes.size() - 1;
}

// Chi2 of an edge at the current estimates, nullopt when the point is behind the
// camera or cannot be projected.
std::optional<double> bundle_edge_chi2(const BundleProblem& lp, const BundleEdge& e) {
  const std::array<const double*, 3> params = lp.parameters(e);
  double p_c[3];
  world_to_camera(params[0], params[1], params[2], p_c);
  if (!(p_c[2] > 0.0)) return std::nullopt;
  return residual_chi2(*e.cost, params.data());
}

bool is_bundle_outlier(const BundleProblem& lp, const BundleEdge& e, const BundleSettings& options) {
  const std::optional<double> chi2 = bundle_edge_chi2(lp, e);
  return !chi2 || *chi2 > (e.stereo ? options.chi2_stereo : options.chi2_mono);
}

namespace {

std::size_t free_keyframes_of(const BundleProblem& lp) {
  std::vector<std::uint8_t> seen(lp.keyframes.size(), 0);
  std::size_t count = 0;
  for (const BundleEdge& e : lp.edges)
    if (e.active && !lp.fixed[e.keyframe] && !seen[e.keyframe]) {
      seen[e.keyframe] = 1;
      ++count;
    }
  return count;
}

// Edges that cannot be evaluated at the current estimates (a point behind the
// camera, e.g. after a merge moved one of them) are outliers: made inactive.
// True when there was one.
bool drop_unevaluable_edges(BundleProblem& lp) {
  bool dropped = false;
  for (BundleEdge& e : lp.edges)
    if (e.active && !bundle_edge_chi2(lp, e)) {
      e.active = false;
      dropped = true;
    }
  return dropped;
}

}  // namespace

int solve_bundle_stage(BundleProblem& lp, bool robust, int iterations, const BundleSettings& options,
                       StopFlagCallback& callback) {
  if (options.own_solver && free_keyframes_of(lp) <= options.dense_schur_max_keyframes) {
    BundleLevenbergOptions lm;
    lm.max_iterations = iterations;
    if (!lp.extra_terms.empty()) lm.initial_radius = options.inertial_trust_region_radius;
    lm.stop = callback.flag();
    const BundleLevenbergResult result = solve_bundle_levenberg(lp, robust, options, lm);
    if (!result.usable && drop_unevaluable_edges(lp))
      return solve_bundle_stage(lp, robust, iterations, options, callback);
    return result.iterations;
  }

  std::vector<std::unique_ptr<ceres::HuberLoss>> extra_losses;  // the problem does not own its losses
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
  auto add_pose = [&](std::size_t k) {
    if (pose_added[k]) return;
    pose_added[k] = 1;
    PoseParameters& pose = lp.poses[k];
    problem.AddParameterBlock(pose.q.data(), 4, &quaternion_manifold);
    problem.AddParameterBlock(pose.t.data(), 3);
    ordering->AddElementToGroup(pose.q.data(), 1);
    ordering->AddElementToGroup(pose.t.data(), 1);
    if (lp.fixed[k]) {
      problem.SetParameterBlockConstant(pose.q.data());
      problem.SetParameterBlockConstant(pose.t.data());
    } else {
      ++free_keyframes;
    }
  };
  for (BundleEdge& e : lp.edges) {
    if (!e.active) continue;
    PoseParameters& pose = lp.poses[e.keyframe];
    double* p = lp.positions[e.point].data();
    add_pose(e.keyframe);
    if (!point_added[e.point]) {
      point_added[e.point] = 1;
      problem.AddParameterBlock(p, 3);
      ordering->AddElementToGroup(p, 0);  // points first: eliminated by the Schur complement
    }
    ceres::LossFunction* loss = nullptr;
    if (robust) loss = e.stereo ? &huber_stereo : &huber_mono;
    problem.AddResidualBlock(e.cost.get(), loss, pose.q.data(), pose.t.data(), p);
  }
  for (const BundleExtraTerm& term : lp.extra_terms) {
    for (const std::size_t k : term.keyframes) add_pose(k);
    ceres::LossFunction* loss = nullptr;
    if (term.huber > 0.0) loss = extra_losses.emplace_back(std::make_unique<ceres::HuberLoss>(term.huber)).get();
    problem.AddResidualBlock(term.cost.get(), loss, term.blocks);
  }
  for (const BundleExtraBlock& block : lp.extra_blocks) {
    if (!problem.HasParameterBlock(block.values.get())) continue;
    ordering->AddElementToGroup(block.values.get(), 1);
    if (block.fixed) problem.SetParameterBlockConstant(block.values.get());
  }

  ceres::Solver::Summary summary;
  if (problem.NumResidualBlocks() == 0) return 0;
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
  if (!lp.extra_terms.empty()) so.initial_trust_region_radius = options.inertial_trust_region_radius;
  ceres::Solve(so, &problem, &summary);
  if (summary.termination_type == ceres::FAILURE && summary.iterations.size() <= 1) {
    // Ceres gave up at its first evaluation (the parameters are untouched): an
    // observation cannot be evaluated where the solve starts. Checked only
    // then, not per solve.
    if (drop_unevaluable_edges(lp)) return solve_bundle_stage(lp, robust, iterations, options, callback);
  }
  return std::max(0, static_cast<int>(summary.iterations.size()) - 1);
}

}  // namespace orbatlas
