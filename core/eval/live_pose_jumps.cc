#include "core/eval/live_pose_jumps.h"

namespace orbatlas {

std::optional<double> LivePoseJumps::add(const Eigen::Vector3d& p_w, MapId map, std::uint64_t maps_edits) {
  std::optional<double> jump;
  if (last_ && (maps_edits != edits_ || map != map_)) {
    const Eigen::Vector3d predicted = before_last_ ? Eigen::Vector3d(2.0 * *last_ - *before_last_) : *last_;
    jump = (p_w - predicted).norm();
  }
  before_last_ = last_;
  last_ = p_w;
  map_ = map;
  edits_ = maps_edits;
  return jump;
}

void LivePoseJumps::lost() {
  last_.reset();
  before_last_.reset();
}

}  // namespace orbatlas
