// Our rotated BRIEF against OpenCV's ORB: the pattern learned from the installed
// library, and the descriptors bit for bit on a rendered Machine Hall frame and
// on noise, through the AVX2 and the plain paths (on OpenCV's blur); and our
// fixed-point blur against OpenCV's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>
#include <string>
#include <utility>

#include "core/common/error.h"
#include "core/features/brief_blur.h"
#include "core/features/brief_pattern.h"
#include "core/features/orb_extractor.h"
#include "core/features/rotated_brief.h"
#include "tests/support/rendered_frames.h"

namespace orbatlas {
namespace {

const cv::Mat& rendered_frame() {
  static const cv::Mat image = test::render_machine_hall_frame(0.4);  // built once for the whole file
  return image;
}

cv::Mat noise_image(int width, int height, unsigned seed) {
  cv::Mat image(height, width, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

// The image inside a buffer with a reflected border, as the pyramid keeps its levels.
cv::Mat bordered_view(const cv::Mat& image, int border) {
  cv::Mat whole;
  cv::copyMakeBorder(image, whole, border, border, border, border, cv::BORDER_REFLECT_101);
  return whole(cv::Rect(border, border, image.cols, image.rows));
}

TEST(BriefPattern, LearnedFromOpenCvAreDistinctPairsWithinThePatch) {
  const BriefPattern& pattern = opencv_brief_pattern();
  std::set<std::pair<int, int>> points;
  for (int i = 0; i < BriefPattern::kPairs; ++i) {
    const auto f = static_cast<std::size_t>(2 * i), s = f + 1;
    EXPECT_FALSE(pattern.x[f] == pattern.x[s] && pattern.y[f] == pattern.y[s]) << "test " << i;
    for (const std::size_t k : {f, s}) {
      EXPECT_LE(std::abs(pattern.x[k]), 15);
      EXPECT_LE(std::abs(pattern.y[k]), 15);
      points.insert({pattern.x[k], pattern.y[k]});
    }
  }
  EXPECT_GT(points.size(), 200u) << "the tests spread over the patch";
  // The pyramid's border leaves room for every turned point.
  EXPECT_LE(RotatedBrief(pattern).reach(), OrbExtractor::kPyramidBorder - 1);
  // Learning again gives the same pairs.
  const BriefPattern again = learn_opencv_brief_pattern();
  EXPECT_EQ(again.x, pattern.x);
  EXPECT_EQ(again.y, pattern.y);
}

TEST(RotatedBrief, BlurRejectsALevelWithoutItsBorder) {
  cv::Mat out;
  const cv::Mat image = noise_image(64, 48, 6);
  EXPECT_THROW(RotatedBrief::blur(image, out), Error);
  EXPECT_THROW(RotatedBrief::blur(bordered_view(image, 2), out), Error);
  EXPECT_THROW(RotatedBrief::blur(cv::Mat(), out), Error);
  EXPECT_THROW(RotatedBrief::blur(bordered_view(cv::Mat(20, 20, CV_8UC3, cv::Scalar(1, 2, 3)), 3), out), Error);
  EXPECT_NO_THROW(RotatedBrief::blur(bordered_view(image, 3), out));
  EXPECT_EQ(out.size(), image.size());
}

// The exact fixed-point blur with our taps, rounded half up: what
// cv::GaussianBlur computes on a whole 8-bit image (its bit-exact path).
cv::Mat exact_fixed_point_blur(const cv::Mat& view) {
  cv::Mat out(view.size(), CV_8UC1);
  for (int y = 0; y < view.rows; ++y)
    for (int x = 0; x < view.cols; ++x) {
      std::int64_t sum = 0;
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx)
          sum += std::int64_t{kBriefBlurTaps[std::abs(dy)]} * kBriefBlurTaps[std::abs(dx)] *
                 view.at<std::uint8_t>(y + dy, x + dx);
      out.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(std::min<std::int64_t>((sum + 32768) >> 16, 255));
    }
  return out;
}

TEST(BriefBlur, TapsAreOpenCvsFixedPointGaussian) {
  const cv::Mat image = noise_image(90, 60, 21);
  cv::Mat theirs;
  cv::GaussianBlur(image, theirs, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);  // a whole image: fixed point
  const cv::Rect inside(3, 3, image.cols - 6, image.rows - 6);
  EXPECT_EQ(cv::norm(exact_fixed_point_blur(image(inside)), theirs(inside), cv::NORM_INF), 0);
  EXPECT_EQ(kBriefBlurTaps[0] + 2 * (kBriefBlurTaps[1] + kBriefBlurTaps[2] + kBriefBlurTaps[3]), 256);
}

// The AVX2 and plain paths bit for bit (every width mod 32, the pyramid's level
// widths, a saturating white patch), and both within a grey level of the exact
// fixed-point blur, off by one at a few pixels in a thousand (measured 0.21 %).
TEST(BriefBlur, BothPathsEqualAndWithinAGreyLevelOfTheExactBlur) {
  std::size_t pixels = 0, off_by_one = 0;
  const auto check = [&](const cv::Mat& image, const std::string& what) {
    const cv::Mat view = bordered_view(image, 3);
    cv::Mat fast, plain;
    brief_blur(view, fast, true);
    brief_blur(view, plain, false);
    ASSERT_EQ(fast.size(), image.size());
    ASSERT_EQ(cv::norm(fast, plain, cv::NORM_INF), 0) << what << " " << image.cols << "x" << image.rows << ": "
                                                      << cv::countNonZero(fast != plain) << " pixels differ";
    const cv::Mat exact = exact_fixed_point_blur(view);
    ASSERT_LE(cv::norm(fast, exact, cv::NORM_INF), 1) << what;
    pixels += image.total();
    off_by_one += static_cast<std::size_t>(cv::countNonZero(fast != exact));
  };
  for (int width = 16; width <= 47; ++width) check(noise_image(width, 23, static_cast<unsigned>(width)), "noise");
  for (const int width : {627, 522, 435, 363, 302, 252, 210}) check(noise_image(width, 40, 77), "level width");
  cv::Mat white = noise_image(90, 40, 5);
  white(cv::Rect(20, 10, 60, 20)).setTo(255);
  check(white, "white patch");
  check(rendered_frame(), "rendered frame");
  const double share = static_cast<double>(off_by_one) / static_cast<double>(pixels);
  EXPECT_LT(share, 0.005) << "of " << pixels << " pixels";
}

// Keypoints at random pixels and angles (a quarter of them at whole degrees,
// where rounding ties are likeliest), described by cv::ORB and by us.
void expect_equal_to_opencv(const cv::Mat& image, unsigned seed) {
  constexpr int kMargin = OrbExtractor::kPyramidBorder;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> ux(kMargin, image.cols - kMargin - 1), uy(kMargin, image.rows - kMargin - 1);
  std::uniform_real_distribution<float> angle(0.0f, 360.0f);
  std::vector<cv::KeyPoint> keys;
  for (int i = 0; i < 3000; ++i) {
    const float a = i % 4 == 0 ? std::floor(angle(rng)) : angle(rng);
    keys.emplace_back(static_cast<float>(ux(rng)), static_cast<float>(uy(rng)), 31.0f, a >= 360.0f ? 0.0f : a, 1.0f, 0);
  }
  const std::size_t count = keys.size();
  cv::Mat reference;
  cv::ORB::create(static_cast<int>(count), 1.2f, 1, kMargin, 0, 2, cv::ORB::HARRIS_SCORE, 31)
      ->compute(image, keys, reference);
  ASSERT_EQ(keys.size(), count) << "OpenCV dropped keypoints";

  cv::Mat blurred;
  RotatedBrief::blur_as_opencv(bordered_view(image, kMargin), blurred);
  const RotatedBrief brief(opencv_brief_pattern());
  for (const bool avx2 : {true, false}) {
    int differing = 0;
    for (std::size_t k = 0; k < keys.size(); ++k) {
      const Descriptor d =
          brief.describe(blurred, static_cast<int>(keys[k].pt.x), static_cast<int>(keys[k].pt.y), keys[k].angle, avx2);
      if (std::memcmp(d.data(), reference.ptr(static_cast<int>(k)), 32) != 0) ++differing;
    }
    EXPECT_EQ(differing, 0) << "of " << keys.size() << " descriptors" << (avx2 ? " (AVX2 path)" : " (plain path)");
  }
}

TEST(RotatedBrief, EqualsOpenCvOrbBitForBitOnBothPaths) {
  expect_equal_to_opencv(rendered_frame(), 11);
  expect_equal_to_opencv(noise_image(752, 480, 12), 13);
}

TEST(RotatedBrief, RejectsAKeypointTooNearTheEdge) {
  const RotatedBrief brief(opencv_brief_pattern());
  const cv::Mat image = noise_image(100, 80, 14);
  const int r = brief.reach();
  EXPECT_NO_THROW(brief.describe(image, r, r, 45.0f));
  EXPECT_THROW(brief.describe(image, r - 1, 40, 0.0f), Error);
  EXPECT_THROW(brief.describe(image, 50, image.rows - r - 1, 0.0f), Error);
  EXPECT_THROW(brief.describe(image, image.cols - r - 1, 40, 0.0f), Error);
}

}  // namespace
}  // namespace orbatlas
