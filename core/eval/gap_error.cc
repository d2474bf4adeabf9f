#include "core/eval/gap_error.h"

#include <vector>

#include "core/eval/alignment.h"

namespace orbatlas {

std::optional<GapError> gap_error(const Trajectory& estimate, const Trajectory& ground_truth, TimestampNs from_ns,
                                  TimestampNs to_ns, TimestampNs max_gap_ns) {
  std::vector<Eigen::Vector3d> outside, truth;
  for (const auto& p : estimate) {
    if (p.t_ns >= from_ns && p.t_ns < to_ns) continue;
    if (const auto g = pose_at(ground_truth, p.t_ns, max_gap_ns)) {
      outside.push_back(p.pose.t);
      truth.push_back(g->t);
    }
  }
  if (outside.size() < 3) return std::nullopt;
  const Similarity3 alignment = align_positions(outside, truth, AlignMode::kSe3);
  std::optional<GapError> result;
  for (const auto& p : estimate) {
    if (p.t_ns < from_ns) continue;
    const auto g = pose_at(ground_truth, p.t_ns, max_gap_ns);
    if (!g) continue;
    const double error = (alignment.apply(p.pose.t) - g->t).norm();
    if (p.t_ns < to_ns) {
      if (!result) result.emplace();
      result->at_end_m = error;
      result->end_t_ns = p.t_ns;
    } else {
      if (result) result->after_m = error;
      break;
    }
  }
  return result;
}

}  // namespace orbatlas
