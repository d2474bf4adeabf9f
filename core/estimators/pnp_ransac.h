#pragma once
// Camera pose from 2D-3D correspondences given as bearing vectors, so it works
// for any camera model (the camera only has to unproject): RANSAC over OpenGV's
// P3P solver (Kneip) on bearings, scored by the angle between each observed
// bearing and the predicted ray, refined on the inliers with OpenGV's nonlinear
// optimisation on bearings. The sampling is seeded: runs are reproducible.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "core/geometry/pose.h"

namespace orbatlas {

struct PnpRansacOptions {
  int max_iterations = 300;
  // Inlier threshold on the angle between bearing and predicted ray. 0.002 rad is
  // ~1 px at 460 px focal length, a bit over 2 px for ORB-SLAM's 5.991 chi2 at level 0.
  double max_angle_rad = 0.003;
  int min_inliers = 15;
  double confidence = 0.99;  // stop early when this sure to have drawn an all-inlier sample
  std::uint64_t seed = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct PnpRansacResult {
  bool success = false;
  Pose3 T_c_w;
  std::vector<std::uint8_t> inliers;  // per correspondence
  int inlier_count = 0;
  int iterations = 0;
};

// bearings[i] (unit, camera frame) observes points_w[i]. Needs at least 4.
PnpRansacResult solve_pnp_ransac(const std::vector<Eigen::Vector3d>& bearings,
                                 const std::vector<Eigen::Vector3d>& points_w, const PnpRansacOptions& options = {});

}  // namespace orbatlas
