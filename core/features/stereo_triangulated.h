#pragma once
// Stereo for fisheye or otherwise non-rectified pairs: match left and right
// keypoints by descriptor (best vs second best), then keep only pairs whose rays,
// triangulated with the known extrinsics, meet in front of both cameras with
// enough parallax and reproject within a few sigma in both images. Works on
// bearing vectors, so any camera model serves.
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/camera/camera.h"
#include "core/features/keypoint.h"
#include "core/geometry/pose.h"

namespace orbatlas {

struct TriangulatedStereoOptions {
  int max_hamming = kHammingHigh;
  double ratio = 0.8;                      // best / second best descriptor distance
  double max_reprojection_sigma2 = 5.991;  // chi2(2 dof, 95%) in units of the level's sigma^2
  double min_parallax_deg = 0.05;
  int sad_half_window = 7;  // sub-pixel refinement window half size (15x15 Lucas-Kanade)

  // Throws Error naming the first value out of range.
  void check() const;
};

struct TriangulatedStereo {
  std::vector<int> right_index;              // per left keypoint; -1 when unmatched
  std::vector<float> depth;                  // z in the left camera frame; -1 when unmatched
  std::vector<Eigen::Vector3d> points_left;  // triangulated point in the left camera frame
  std::size_t matched() const;
};

// Keypoints need their bearings (compute_keypoint_geometry). T_l_r: right camera
// in the left camera frame. level_sigma2: per pyramid level (scale^2).
// left_image / right_image (full resolution, CV_8UC1) enable sub-pixel refinement:
// the right position is re-found by Lucas-Kanade (cv::calcOpticalFlowPyrLK) from
// the left keypoint, starting at the descriptor match (keypoints are quantised to
// their level's pixel grid, up to 2 px at level 7). Pass empty images to skip.
TriangulatedStereo match_stereo_triangulated(const Camera& left_camera, const ImageFeatures& left,
                                             const Camera& right_camera, const ImageFeatures& right, const Pose3& T_l_r,
                                             const std::vector<double>& level_sigma2, const cv::Mat& left_image,
                                             const cv::Mat& right_image, const TriangulatedStereoOptions& options = {});

// Midpoint of the closest points of two rays from the origins o1, o2 with unit
// directions d1, d2; false when they are (nearly) parallel or meet behind either origin.
bool triangulate_rays(const Eigen::Vector3d& o1, const Eigen::Vector3d& d1, const Eigen::Vector3d& o2,
                      const Eigen::Vector3d& d2, Eigen::Vector3d* point);

}  // namespace orbatlas
