#include "core/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

#include "core/common/error.h"

namespace orbatlas {

Coverage trajectory_coverage(const Trajectory& estimate, const std::vector<std::pair<TimestampNs, TimestampNs>>& spans,
                             TimestampNs max_step_ns) {
  Coverage c;
  std::vector<TimestampNs> all;
  for (const StampedPose& p : estimate) all.push_back(p.t_ns);
  std::sort(all.begin(), all.end());
  if (max_step_ns <= 0 && all.size() >= 2) {
    std::vector<TimestampNs> steps;
    for (std::size_t i = 1; i < all.size(); ++i) steps.push_back(all[i] - all[i - 1]);
    std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
    max_step_ns = std::max<TimestampNs>(3 * steps[steps.size() / 2], 1'000'000);
  }
  TimestampNs covered = 0, length = 0;
  for (const auto& [begin, end] : spans) {
    if (end <= begin) continue;
    length += end - begin;
    const auto first = std::lower_bound(all.begin(), all.end(), begin);
    const auto last = std::upper_bound(all.begin(), all.end(), end);
    for (auto it = first; it != last && std::next(it) != last; ++it)
      if (*std::next(it) - *it <= max_step_ns) covered += *std::next(it) - *it;
  }
  if (length <= 0) return c;
  c.span_s = ns_to_s(length);
  c.covered_s = ns_to_s(covered);
  c.fraction = std::clamp(c.covered_s / c.span_s, 0.0, 1.0);
  return c;
}

void EvalOptions::check() const {
  ORBATLAS_CHECK(align == AlignMode::kNone || align == AlignMode::kSe3 || align == AlignMode::kSim3,
                 "eval: align must be none, se3 or sim3, not " << static_cast<int>(align));
  association.check();
  ORBATLAS_CHECK(rpe_delta_ns > 0, "eval: rpe_delta_ns must be > 0, not " << rpe_delta_ns);
  if (segment_lengths_m)
    for (const double l : *segment_lengths_m)
      ORBATLAS_CHECK(std::isfinite(l) && l > 0.0, "eval: a segment length must be > 0 m, not " << l);
}

EvalResult evaluate_trajectory(const Trajectory& estimate, const Trajectory& body_truth, const EvalOptions& options) {
  options.check();
  const Trajectory moved = options.estimate_T_b_x ? attached_frame(body_truth, *options.estimate_T_b_x) : Trajectory();
  const Trajectory& ground_truth = options.estimate_T_b_x ? moved : body_truth;
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
          << format_seconds_exact(ground_truth.front().t_ns) << " .. " << format_seconds_exact(ground_truth.back().t_ns)
          << " s";
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
  if (options.segment_lengths_m) {
    const std::vector<double> lengths = options.segment_lengths_m->empty()
                                            ? kitti_lengths_for_path(ground_truth_path_length(association.pairs))
                                            : *options.segment_lengths_m;
    result.segments = kitti_relative_errors(association.pairs, result.alignment.scale, lengths);
  }
  result.coverage = trajectory_coverage(
      estimate, options.spans.empty() ? std::vector<std::pair<TimestampNs, TimestampNs>>{{ground_truth.front().t_ns,
                                                                                          ground_truth.back().t_ns}}
                                      : options.spans);
  return result;
}

}  // namespace orbatlas
