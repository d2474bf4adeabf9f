#pragma once
// The blur ORB applies to a pyramid level before its BRIEF tests: 7x7 Gaussian,
// sigma 2, with OpenCV's fixed-point taps (56, 48, 34, 18 from the centre out,
// summing to 256: cv::GaussianBlur's bit-exact kernel, the one ORB-SLAM3's
// blur of a whole level image gets). Rows are filtered exactly; columns with
// 16-bit products, so a pixel can end one grey level off the exact rounding
// (tests/features/test_rotated_brief.cc measures how often). Pixels outside the level
// are read from its bordered buffer, not extrapolated.
//
// Why not cv::GaussianBlur: on a view into a bordered buffer OpenCV takes its
// generic float filter, about 0.8 ms of an image's 3.6 ms of ORB extraction
// (it showed in profiles); this takes about 0.45 ms with AVX2.
#include <opencv2/core/mat.hpp>

namespace orbatlas {

// The kernel's taps from the centre out.
inline constexpr int kBriefBlurTaps[4] = {56, 48, 34, 18};

// Blurs `view` (CV_8UC1 with at least 3 valid pixels of its buffer on every
// side; the caller checks) into `dst`, reallocated to its size and not sharing
// its memory. use_avx2 false forces the plain path, which gives the same bits.
void brief_blur(const cv::Mat& view, cv::Mat& dst, bool use_avx2 = true);

}  // namespace orbatlas
