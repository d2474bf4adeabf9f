#pragma once
// Aligning an estimated trajectory to ground truth (Umeyama, 1991): a rigid
// transform (se3), a similarity with scale (sim3, for monocular estimates), or none.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string_view>
#include <vector>

#include "core/geometry/pose.h"

namespace orbatlas {

enum class AlignMode { kNone, kSe3, kSim3 };

// "none" | "se3" | "sim3"; empty for anything else.
std::optional<AlignMode> parse_align_mode(std::string_view text);
const char* align_mode_name(AlignMode mode);

// p_gt = scale * (rotation * p_est) + translation.
struct Similarity3 {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double scale = 1.0;

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return scale * (rotation * p) + translation; }
  // An estimated body pose T_w_b in the ground-truth world (position scaled).
  Pose3 apply(const Pose3& T_w_b) const { return Pose3(rotation * T_w_b.q, apply(T_w_b.t)); }
};

// The least-squares transform taking estimate[i] onto ground_truth[i]. kNone gives
// the identity. Throws Error with fewer than 3 points, or for sim3 when the
// estimate has no spread (all positions equal).
Similarity3 align_positions(const std::vector<Eigen::Vector3d>& estimate,
                            const std::vector<Eigen::Vector3d>& ground_truth, AlignMode mode);

}  // namespace orbatlas
