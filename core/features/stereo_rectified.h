#pragma once
// Stereo for pinhole pairs (EuRoC): rectify once from the calibration, then
// match each left keypoint along its row in the right image by descriptor
// distance, refine the disparity to sub-pixel by SAD on patches, and keep a
// depth per left keypoint after rejecting outliers (ORB-SLAM's scheme).
#include <opencv2/core/mat.hpp>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/features/keypoint.h"

namespace orbatlas {

// Rectification of a pinhole-radtan pair. The rectified cameras are distortion-
// free pinholes with equal intrinsics; their bodies poses are rotated by the
// rectifying rotations, so rectified_left().T_b_c is what tracking must use.
class StereoRectifier {
 public:
  StereoRectifier(const CameraCalibration& left, const CameraCalibration& right);

  // Rectified images of the same size as the inputs (CV_8UC1).
  void rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect, cv::Mat& right_rect) const;
  // One side only (the two may run on different threads).
  void rectify_left(const cv::Mat& left, cv::Mat& left_rect) const;
  void rectify_right(const cv::Mat& right, cv::Mat& right_rect) const;

  const CameraCalibration& rectified_left() const { return rect_left_; }
  const CameraCalibration& rectified_right() const { return rect_right_; }
  double baseline() const { return baseline_; }            // metres
  double bf() const { return baseline_ * rect_left_.fx; }  // baseline * focal (pixels * m)

 private:
  CameraCalibration rect_left_, rect_right_;
  double baseline_ = 0.0;
  // cv::remap's fixed-point form of the float maps (CV_16SC2 whole pixels and
  // CV_16UC1 interpolation-table indices): the same result, without remap
  // converting the float maps again on every image (it showed in profiles).
  cv::Mat map_left_xy_, map_left_frac_, map_right_xy_, map_right_frac_;
  cv::Size size_;
};

struct StereoMatchOptions {
  int max_hamming = (kHammingLow + kHammingHigh) / 2;
  int sad_half_window = 5;            // 11x11 patches
  int sad_search = 3;                 // +- full-resolution pixels around the descriptor match (plus the level scale)
  double min_depth_baselines = 1.0;   // nearest depth accepted, in baselines (max disparity = fx)
  double outlier_factor = 1.5 * 1.4;  // SAD cost above factor * median is rejected

  // Throws Error naming the first value out of range.
  void check() const;
};

struct StereoDepths {
  std::vector<float> u_right;  // right image column per left keypoint; -1 when unmatched
  std::vector<float> depth;    // metres per left keypoint; -1 when unmatched
  std::size_t matched() const;
};

// left/right: features of the rectified images, extracted with the same pyramid
// settings; *_pyramid: the extractors' pyramids of those images; scale_factors of
// the levels. Keypoints must be on rectified images (rows are epipolar lines).
StereoDepths match_stereo_rectified(const ImageFeatures& left, const std::vector<cv::Mat>& left_pyramid,
                                    const ImageFeatures& right, const std::vector<cv::Mat>& right_pyramid,
                                    const std::vector<double>& scale_factors, double bf, double baseline,
                                    const StereoMatchOptions& options = {});

}  // namespace orbatlas
