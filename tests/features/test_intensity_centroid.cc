// ORB's orientation patch and moments: the rows are the disc u^2 + v^2 <= 234,
// and the AVX2 and plain paths give the moments a direct sum over that disc gives.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <random>

#include "core/features/intensity_centroid.h"

namespace orbatlas {
namespace {

TEST(IntensityCentroid, RowsAreTheDiscOfOrb) {
  const IntensityCentroid centroid;
  for (int v = -15; v <= 15; ++v)
    for (int u = -15; u <= 15; ++u)
      EXPECT_EQ(std::abs(u) <= centroid.half_width(v), u * u + v * v <= 234) << "(" << u << ", " << v << ")";
}

TEST(IntensityCentroid, BothPathsGiveTheDiscsMoments) {
  cv::Mat image(120, 160, CV_8UC1);
  cv::RNG(21).fill(image, cv::RNG::UNIFORM, 0, 256);
  image.row(60).setTo(255);  // saturated rows and columns too
  image.col(80).setTo(255);
  const IntensityCentroid centroid;
  std::mt19937 rng(22);
  std::uniform_int_distribution<int> ux(16, image.cols - 17), uy(15, image.rows - 16);
  for (int i = 0; i < 500; ++i) {
    const int x = i == 0 ? 80 : ux(rng), y = i == 0 ? 60 : uy(rng);
    int m01 = 0, m10 = 0;
    for (int v = -15; v <= 15; ++v)
      for (int u = -15; u <= 15; ++u)
        if (u * u + v * v <= 234) {
          m10 += u * image.at<std::uint8_t>(y + v, x + u);
          m01 += v * image.at<std::uint8_t>(y + v, x + u);
        }
    for (const bool avx2 : {true, false}) {
      const IntensityCentroid::Moments m = centroid.moments(image, x, y, avx2);
      ASSERT_EQ(m.m10, m10) << "(" << x << ", " << y << ")" << (avx2 ? " AVX2" : " plain");
      ASSERT_EQ(m.m01, m01) << "(" << x << ", " << y << ")" << (avx2 ? " AVX2" : " plain");
    }
  }
}

}  // namespace
}  // namespace orbatlas
