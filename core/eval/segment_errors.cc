#include "core/eval/segment_errors.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/common/error.h"

namespace orbatlas {

std::vector<double> kitti_benchmark_lengths() { return {100, 200, 300, 400, 500, 600, 700, 800}; }

std::vector<double> kitti_lengths_for_path(double path_m) {
  std::vector<double> lengths;
  for (const double l : kitti_benchmark_lengths())
    if (l < path_m) lengths.push_back(l);
  if (!lengths.empty()) return lengths;
  for (int tenth = 1; tenth <= 8; ++tenth) {
    const double l = std::round(path_m * tenth / 10.0);
    if (l >= 1.0 && (lengths.empty() || l > lengths.back())) lengths.push_back(l);
  }
  return lengths;
}

namespace {

// The distance along the ground truth from the first pair to each pair.
std::vector<double> distances(const std::vector<PosePair>& pairs) {
  std::vector<double> d(pairs.size(), 0.0);
  for (std::size_t i = 1; i < pairs.size(); ++i)
    d[i] = d[i - 1] + (pairs[i].ground_truth.t - pairs[i - 1].ground_truth.t).norm();
  return d;
}

}  // namespace

double ground_truth_path_length(const std::vector<PosePair>& pairs) {
  return pairs.empty() ? 0.0 : distances(pairs).back();
}

KittiErrors kitti_relative_errors(const std::vector<PosePair>& pairs, double scale,
                                  const std::vector<double>& lengths_m, std::size_t step) {
  ORBATLAS_CHECK(step > 0, "eval: the segments' step must be at least one pose");
  for (const double l : lengths_m)
    ORBATLAS_CHECK(std::isfinite(l) && l > 0.0, "eval: a segment length must be > 0 m, not " << l);
  KittiErrors out;
  const std::vector<double> dist = distances(pairs);
  out.path_m = dist.empty() ? 0.0 : dist.back();
  double sum_t = 0.0, sum_r = 0.0;
  for (const double length : lengths_m) {
    SegmentErrors by{length, 0, 0.0, 0.0};
    std::size_t last = 0;
    for (std::size_t first = 0; first < pairs.size(); first += step) {
      // The first pose at least `length` further along (the devkit's lastFrameFromSegmentLength).
      last = std::max(last, first);
      while (last < pairs.size() && dist[last] < dist[first] + length) ++last;
      if (last >= pairs.size()) break;
      const Pose3 gt_rel = pairs[first].ground_truth.inverse() * pairs[last].ground_truth;
      Pose3 est_rel = pairs[first].estimate.inverse() * pairs[last].estimate;
      est_rel.t *= scale;
      const Pose3 error = est_rel.inverse() * gt_rel;
      const double angle = Eigen::AngleAxisd(error.q.normalized()).angle();
      by.trans_percent += error.t.norm() / length;
      by.rot_deg_per_m += angle / length;
      ++by.segments;
    }
    sum_t += by.trans_percent;
    sum_r += by.rot_deg_per_m;
    out.segments += by.segments;
    if (by.segments > 0) {
      by.trans_percent *= 100.0 / static_cast<double>(by.segments);
      by.rot_deg_per_m *= 180.0 / std::numbers::pi / static_cast<double>(by.segments);
    }
    out.by_length.push_back(by);
  }
  if (out.segments > 0) {
    out.trans_percent = 100.0 * sum_t / static_cast<double>(out.segments);
    out.rot_deg_per_m = 180.0 / std::numbers::pi * sum_r / static_cast<double>(out.segments);
  }
  return out;
}

}  // namespace orbatlas
