#include "core/eval/evaluate.h"

#include "core/common/error.h"

namespace orbatlas {

EvalResult evaluate_trajectory(const Trajectory& estimate, const Trajectory& ground_truth, const EvalOptions& options) {
  EvalResult result;
  result.align = options.align;
  result.est_poses = estimate.size();
  result.gt_poses = ground_truth.size();
  const Association association = associate(estimate, ground_truth, options.association);
  result.matched = association.pairs.size();
  if (result.matched < 3) {
    std::ostringstream msg;
    msg << "only " << result.matched << " of " << estimate.size()
        << " estimated poses match the ground truth in time (at least 3 are needed)";
    if (!estimate.empty() && !ground_truth.empty())
      msg << "; estimate spans " << format_seconds_exact(estimate.front().t_ns) << " .. "
          << format_seconds_exact(estimate.back().t_ns) << " s, ground truth "
          << format_seconds_exact(ground_truth.front().t_ns) << " .. "
          << format_seconds_exact(ground_truth.back().t_ns) << " s";
    throw Error(msg.str());
  }

  std::vector<Eigen::Vector3d> est_positions, gt_positions;
  est_positions.reserve(result.matched);
  gt_positions.reserve(result.matched);
  for (const PosePair& p : association.pairs) {
    est_positions.push_back(p.estimate.t);
    gt_positions.push_back(p.ground_truth.t);
  }
  result.alignment = align_positions(est_positions, gt_positions, options.align);
  result.ate = error_stats(ate_errors(association.pairs, result.alignment));
  result.rpe = relative_pose_error(association.pairs, result.alignment.scale, options.rpe_delta_ns);
  return result;
}

}  // namespace orbatlas
