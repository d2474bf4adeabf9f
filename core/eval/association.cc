#include "core/eval/association.h"

namespace orbatlas {

Association associate(const Trajectory& estimate, const Trajectory& ground_truth, const AssociationOptions& options) {
  check_strictly_increasing(estimate, "estimated trajectory");
  check_strictly_increasing(ground_truth, "ground-truth trajectory");
  Association result;
  result.pairs.reserve(estimate.size());
  for (const StampedPose& e : estimate) {
    const std::optional<Pose3> gt = pose_at(ground_truth, e.t_ns, options.max_gap_ns, options.exact_tol_ns);
    if (gt) {
      result.pairs.push_back(PosePair{e.t_ns, e.pose, *gt});
    } else {
      ++result.unmatched;
    }
  }
  return result;
}

}  // namespace orbatlas
