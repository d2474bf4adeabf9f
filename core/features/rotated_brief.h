#pragma once
// Rotated BRIEF on a blurred level image, bit for bit OpenCV's ORB descriptor:
// each pair's points turned by the keypoint's angle (in float, as OpenCV does),
// rounded to the nearest pixel and compared; bit b of byte j is pair 8j + b.
// With AVX2, eight tests at a time (the same float arithmetic, no fused
// multiply-add, the same rounding).
#include <array>
#include <opencv2/core/mat.hpp>

#include "core/features/brief_pattern.h"
#include "core/features/descriptor.h"

namespace orbatlas {

class RotatedBrief {
 public:
  explicit RotatedBrief(const BriefPattern& pattern);

  // The blur before the tests: 7x7 Gaussian, sigma 2, on the level image as a
  // view into its bordered buffer (at least 3 valid pixels on every side,
  // checked), in fixed point (brief_blur.h). use_avx2 false forces the plain
  // path (the same bits). dst must not share the level's memory (checked).
  static void blur(const cv::Mat& level_view, cv::Mat& dst, bool use_avx2 = true);
  // The same blur as cv::ORB computes it: cv::GaussianBlur, BORDER_REFLECT_101,
  // which on such a view takes OpenCV's generic filter in float with unrounded
  // taps, so a pixel can differ from blur()'s by a grey level. About twice as
  // slow; with it our descriptors are cv::ORB's bit for bit
  // (OrbExtractorOptions::opencv_blur).
  static void blur_as_opencv(const cv::Mat& level_view, cv::Mat& dst);

  // blurred: CV_8UC1, the level image after gaussian_blur_7x7_sigma2. (x, y): a
  // pixel at least reach() from every edge (checked). angle_deg: the keypoint's
  // orientation, [0, 360). use_avx2: false forces the plain path (tests).
  Descriptor describe(const cv::Mat& blurred, int x, int y, float angle_deg, bool use_avx2 = true) const;

  // The farthest a turned, rounded point can land from the keypoint along an axis.
  int reach() const { return reach_; }

 private:
  // The pattern as floats: pair i's first point (first_x_[i], first_y_[i]).
  alignas(32) std::array<float, BriefPattern::kPairs> first_x_{}, first_y_{}, second_x_{}, second_y_{};
  int reach_ = 0;
};

}  // namespace orbatlas
