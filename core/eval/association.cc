#include "core/eval/association.h"

#include "core/common/error.h"

namespace orbatlas {

void AssociationOptions::check() const {
  ORBATLAS_CHECK(max_gap_ns >= 0, "association: max_gap_ns must be >= 0, not " << max_gap_ns);
  ORBATLAS_CHECK(exact_tol_ns >= 0, "association: exact_tol_ns must be >= 0, not " << exact_tol_ns);
}

Association associate(const Trajectory& estimate, const Trajectory& ground_truth, const AssociationOptions& options) {
  options.check();
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
