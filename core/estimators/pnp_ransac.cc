#include "core/estimators/pnp_ransac.h"

#include <algorithm>
#include <cmath>
#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <random>

#include "core/common/error.h"

namespace orbatlas {
namespace {

Pose3 to_T_c_w(const opengv::transformation_t& T_w_c) {
  const Eigen::Matrix3d R_w_c = T_w_c.leftCols<3>();
  const Eigen::Vector3d t_w_c = T_w_c.col(3);
  return Pose3(Eigen::Quaterniond(R_w_c), t_w_c).inverse();
}

int count_inliers(const Pose3& T_c_w, const opengv::bearingVectors_t& bearings, const opengv::points_t& points,
                  double min_cos, std::vector<std::uint8_t>* inliers) {
  int n = 0;
  inliers->assign(bearings.size(), 0);
  for (std::size_t i = 0; i < bearings.size(); ++i) {
    const Eigen::Vector3d ray = T_c_w * points[i];
    const double norm = ray.norm();
    if (norm <= 0.0) continue;
    if (ray.dot(bearings[i]) / norm >= min_cos) {
      (*inliers)[i] = 1;
      ++n;
    }
  }
  return n;
}

}  // namespace

void PnpRansacOptions::check() const {
  ORBATLAS_CHECK(max_iterations >= 1, "PnP: max_iterations must be >= 1, not " << max_iterations);
  ORBATLAS_CHECK(max_angle_rad > 0.0 && max_angle_rad <= M_PI,
                 "PnP: max_angle_rad must be in (0, pi], not " << max_angle_rad);
  ORBATLAS_CHECK(min_inliers >= 0, "PnP: min_inliers must be >= 0, not " << min_inliers);
  ORBATLAS_CHECK(confidence >= 0.0 && confidence < 1.0, "PnP: confidence must be in [0, 1), not " << confidence);
}

PnpRansacResult solve_pnp_ransac(const std::vector<Eigen::Vector3d>& bearings,
                                 const std::vector<Eigen::Vector3d>& points_w, const PnpRansacOptions& options) {
  ORBATLAS_CHECK(bearings.size() == points_w.size(),
                 "PnP: " << bearings.size() << " bearings for " << points_w.size() << " points");
  PnpRansacResult result;
  const std::size_t n = bearings.size();
  if (n < 4 || static_cast<int>(n) < options.min_inliers) return result;

  opengv::bearingVectors_t b(n);
  opengv::points_t p(points_w.begin(), points_w.end());
  for (std::size_t i = 0; i < n; ++i) b[i] = bearings[i].normalized();
  opengv::absolute_pose::CentralAbsoluteAdapter adapter(b, p);

  const double min_cos = std::cos(options.max_angle_rad);
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  std::vector<std::uint8_t> inliers;
  int best = 0;
  Pose3 best_pose;
  int needed = options.max_iterations;
  int it = 0;
  for (; it < needed; ++it) {
    std::vector<int> sample;
    while (sample.size() < 3) {
      const int k = static_cast<int>(pick(rng));
      if (std::find(sample.begin(), sample.end(), k) == sample.end()) sample.push_back(k);
    }
    const opengv::transformations_t solutions = opengv::absolute_pose::p3p_kneip(adapter, sample);
    for (const auto& T_w_c : solutions) {
      if (!T_w_c.allFinite()) continue;
      const Pose3 T_c_w = to_T_c_w(T_w_c);
      const int count = count_inliers(T_c_w, b, p, min_cos, &inliers);
      if (count > best) {
        best = count;
        best_pose = T_c_w;
        // Iterations for `confidence` of drawing 3 inliers at the current inlier ratio.
        const double ratio = static_cast<double>(count) / static_cast<double>(n);
        const double p_good = ratio * ratio * ratio;
        if (p_good > 0.0 && p_good < 1.0) {
          const double k = std::log(1.0 - options.confidence) / std::log(1.0 - p_good);
          needed = std::min(options.max_iterations, std::max(it + 1, static_cast<int>(std::ceil(k))));
        } else if (p_good >= 1.0) {
          needed = it + 1;
        }
      }
    }
  }
  result.iterations = it;
  if (best < options.min_inliers) return result;

  // Refine on the inliers (twice: the inlier set may grow with the better pose).
  Pose3 pose = best_pose;
  for (int round = 0; round < 2; ++round) {
    count_inliers(pose, b, p, min_cos, &inliers);
    std::vector<int> indices;
    for (std::size_t i = 0; i < n; ++i)
      if (inliers[i]) indices.push_back(static_cast<int>(i));
    if (indices.size() < 6) break;
    const Pose3 T_w_c = pose.inverse();
    adapter.sett(T_w_c.t);
    adapter.setR(T_w_c.rotation());
    const opengv::transformation_t refined = opengv::absolute_pose::optimize_nonlinear(adapter, indices);
    if (!refined.allFinite()) break;
    pose = to_T_c_w(refined);
  }
  result.inlier_count = count_inliers(pose, b, p, min_cos, &result.inliers);
  result.T_c_w = pose;
  result.success = result.inlier_count >= options.min_inliers;
  return result;
}

}  // namespace orbatlas
