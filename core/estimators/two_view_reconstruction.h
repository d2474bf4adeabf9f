#pragma once
// Monocular map initialisation from two views (ORB-SLAM's Initializer, issue
// 20): a homography and a fundamental matrix are estimated in parallel by
// RANSAC on the same minimal sets of eight matches, each scored by its
// symmetric transfer error; the homography is chosen when it explains the
// matches about as well as the fundamental matrix (a planar or low-parallax
// scene: R_H = S_H / (S_H + S_F) > 0.45), else the fundamental matrix. The
// relative pose is recovered from the chosen model (the essential matrix's
// four solutions, the homography's up to eight), each checked by triangulating
// the inliers: points in front of both cameras, within the reprojection error,
// with enough parallax; the best must be clearly better than the second.
//
// The matches are given on the normalised image plane (z = 1, what a camera
// model's unprojection gives), so any camera model serves whose field of view
// keeps the points in front; the error thresholds are in pixels and converted
// with the camera's focal length. The translation comes out with unit norm:
// the map's scale is arbitrary. The sampling is seeded: runs are reproducible.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry/pose.h"

namespace orbatlas {

struct TwoViewOptions {
  int iterations = 200;            // RANSAC sets (ORB-SLAM: 200)
  double sigma_px = 1.0;           // measurement noise at the finest pyramid level
  double focal_px = 458.0;         // converts sigma_px to the normalised plane
  double homography_ratio = 0.45;  // R_H above this: the homography (ORB-SLAM's paper)
  double min_parallax_deg = 1.0;   // median-of-the-best parallax of the triangulated points
  int min_triangulated = 50;
  // The best pose must triangulate this fraction of the model's inliers...
  double min_good_fraction = 0.9;
  // ... and the second best at most this fraction of the best's points (else
  // ambiguous): ORB-SLAM's 0.7 for the fundamental matrix, 0.75 for the homography.
  double max_second_ratio = 0.7;
  double max_second_ratio_homography = 0.75;
  std::uint64_t seed = 1;

  // Throws Error naming the first value out of range.
  void check() const;
};

enum class TwoViewModel { kNone, kHomography, kFundamental };
const char* to_string(TwoViewModel model);

struct TwoViewResult {
  bool success = false;
  std::string failure;  // why not, when !success
  TwoViewModel model = TwoViewModel::kNone;
  double score_homography = 0.0, score_fundamental = 0.0;
  double homography_ratio = 0.0;  // R_H
  Pose3 T_c2_c1;                  // the second camera from the first; |t| = 1
  // Per match: triangulated (inlier of the chosen model, in front of both
  // cameras, within the reprojection error) and its position in camera 1.
  std::vector<std::uint8_t> triangulated;
  std::vector<Eigen::Vector3d> points_c1;
  int triangulated_count = 0;
  double parallax_deg = 0.0;
  Eigen::Matrix3d H_21 = Eigen::Matrix3d::Zero();  // x2 ~ H_21 x1 (normalised plane)
  Eigen::Matrix3d F_21 = Eigen::Matrix3d::Zero();  // x2^T F_21 x1 = 0 (the essential matrix up to scale)
};

// x1[i] in the first view matches x2[i] in the second (normalised image
// coordinates). Needs at least 8 matches; fewer, or no consistent
// reconstruction, gives success = false with the reason.
TwoViewResult reconstruct_two_views(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2,
                                    const TwoViewOptions& options = {});

// The model pieces, exposed for the tests.
// Homography x2 ~ H x1 from >= 4 matches (normalised DLT); zero when degenerate.
Eigen::Matrix3d homography_dlt(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2);
// Fundamental matrix x2^T F x1 = 0 from >= 8 matches (normalised eight-point, rank 2).
Eigen::Matrix3d fundamental_eight_point(const std::vector<Eigen::Vector2d>& x1, const std::vector<Eigen::Vector2d>& x2);

}  // namespace orbatlas
