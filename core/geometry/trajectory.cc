#include "core/geometry/trajectory.h"

#include <algorithm>
#include <string>

#include "core/common/error.h"

namespace orbatlas {

std::optional<Pose3> pose_at(const Trajectory& trajectory, TimestampNs t, TimestampNs max_gap_ns,
                             TimestampNs exact_tol_ns) {
  if (trajectory.empty()) return std::nullopt;
  const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), t,
                                   [](const StampedPose& s, TimestampNs v) { return s.t_ns < v; });
  // Nearest sample within the exact tolerance.
  if (it != trajectory.end() && it->t_ns - t <= exact_tol_ns) return it->pose;
  if (it != trajectory.begin() && t - std::prev(it)->t_ns <= exact_tol_ns) return std::prev(it)->pose;
  if (it == trajectory.end() || it == trajectory.begin()) return std::nullopt;
  const StampedPose& a = *std::prev(it);
  const StampedPose& b = *it;
  if (b.t_ns - a.t_ns > max_gap_ns) return std::nullopt;
  const double alpha = static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  return interpolate(a.pose, b.pose, alpha);
}

void check_strictly_increasing(const Trajectory& trajectory, const char* what) {
  for (std::size_t i = 1; i < trajectory.size(); ++i) {
    if (trajectory[i].t_ns <= trajectory[i - 1].t_ns)
      throw DataError(std::string(what) + ": timestamps not strictly increasing at pose " + std::to_string(i) + " (" +
                      format_seconds_exact(trajectory[i - 1].t_ns) + " then " +
                      format_seconds_exact(trajectory[i].t_ns) + ")");
  }
}

Trajectory attached_frame(const Trajectory& trajectory, const Pose3& T_b_x) {
  Trajectory out = trajectory;
  for (auto& s : out) s.pose = s.pose * T_b_x;
  return out;
}

Trajectory join_trajectories(const std::vector<Trajectory>& parts, const char* what) {
  Trajectory all;
  for (const Trajectory& part : parts) all.insert(all.end(), part.begin(), part.end());
  std::stable_sort(all.begin(), all.end(), [](const StampedPose& a, const StampedPose& b) { return a.t_ns < b.t_ns; });
  check_strictly_increasing(all, what);
  return all;
}

}  // namespace orbatlas
