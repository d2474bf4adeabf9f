#include "core/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace orbatlas {

ErrorStats error_stats(std::vector<double> errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  double sum = 0, sum_sq = 0;
  for (const double e : errors) {
    sum += e;
    sum_sq += e * e;
    s.max = std::max(s.max, e);
  }
  const double n = static_cast<double>(errors.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  const std::size_t mid = errors.size() / 2;
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(mid), errors.end());
  s.median = errors[mid];
  if (errors.size() % 2 == 0) {
    const double below = *std::max_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = 0.5 * (s.median + below);
  }
  return s;
}

std::vector<double> ate_errors(const std::vector<PosePair>& pairs, const Similarity3& alignment) {
  std::vector<double> errors;
  errors.reserve(pairs.size());
  for (const PosePair& p : pairs) errors.push_back((p.ground_truth.t - alignment.apply(p.estimate.t)).norm());
  return errors;
}

RpeStats relative_pose_error(const std::vector<PosePair>& pairs, double scale, TimestampNs delta_ns) {
  RpeStats stats;
  double sum_t = 0, sum_r = 0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < pairs.size() && pairs[j].t_ns - pairs[i].t_ns < delta_ns) ++j;
    if (j >= pairs.size()) break;
    if (pairs[j].t_ns - pairs[i].t_ns > delta_ns + delta_ns / 2) continue;
    const Pose3 gt_rel = pairs[i].ground_truth.inverse() * pairs[j].ground_truth;
    Pose3 est_rel = pairs[i].estimate.inverse() * pairs[j].estimate;
    est_rel.t *= scale;
    const Pose3 error = gt_rel.inverse() * est_rel;
    sum_t += error.t.squaredNorm();
    const double angle = rotation_distance(gt_rel, est_rel);
    sum_r += angle * angle;
    ++stats.pairs;
  }
  if (stats.pairs > 0) {
    const double n = static_cast<double>(stats.pairs);
    stats.trans_rmse_m = std::sqrt(sum_t / n);
    stats.rot_rmse_deg = std::sqrt(sum_r / n) * 180.0 / std::numbers::pi;
  }
  return stats;
}

}  // namespace orbatlas
