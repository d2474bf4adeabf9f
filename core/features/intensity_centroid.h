#pragma once
// ORB's keypoint orientation: the intensity centroid of the circular patch of
// radius 15 around the keypoint (ORB's rows of half-width umax, the disc
// u^2 + v^2 <= 234), on the unblurred level image. The moments are integers;
// the AVX2 path sums whole rows of the patch at once and gives the same ones.
#include <array>
#include <cstdint>
#include <opencv2/core/mat.hpp>

namespace orbatlas {

class IntensityCentroid {
 public:
  static constexpr int kRadius = 15;

  IntensityCentroid();

  struct Moments {
    int m01 = 0, m10 = 0;  // sums of v * I and u * I over the patch (u right, v down)
  };
  // (x, y): a pixel at least kRadius + 1 from the level's right edge and kRadius
  // from the others (the AVX2 path reads 32 pixels from x - 15); not checked,
  // the extractor's keypoints are 19 px in.
  Moments moments(const cv::Mat& level, int x, int y, bool use_avx2 = true) const;
  // The angle of (m10, m01) in degrees, [0, 360), as cv::fastAtan2 gives it.
  float angle(const cv::Mat& level, int x, int y, bool use_avx2 = true) const;

  // Half-width of row v (|v| <= 15) of the patch.
  int half_width(int v) const { return umax_[static_cast<std::size_t>(v < 0 ? -v : v)]; }

 private:
  std::array<int, kRadius + 2> umax_{};
  // Row v's weights for 32 pixels from u = -15: u (row_u_) and v (row_v_) where
  // |u| <= umax[v], zero elsewhere.
  alignas(32) std::array<std::array<std::int8_t, 32>, kRadius + 1> row_u_{}, row_v_{};
};

}  // namespace orbatlas
