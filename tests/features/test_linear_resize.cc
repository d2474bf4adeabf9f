// Our bilinear resize against cv::resize(INTER_LINEAR), bit for bit: the ORB
// pyramid's chain of sizes from a 752x480 camera and others, shrinking and
// growing, on noise, on saturated patches and on a rendered Machine Hall frame,
// through the AVX2 and the plain paths, with the source a view into a larger
// buffer as the pyramid keeps its levels.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "core/common/error.h"
#include "core/features/linear_resize.h"
#include "tests/support/rendered_frames.h"

namespace orbatlas {
namespace {

cv::Mat noise_image(cv::Size size, unsigned seed) {
  cv::Mat image(size, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

// The image inside a larger buffer (another step, bytes around it).
cv::Mat framed_view(const cv::Mat& image, int border) {
  cv::Mat whole;
  cv::copyMakeBorder(image, whole, border, border, border, border, cv::BORDER_CONSTANT, 255);
  return whole(cv::Rect(border, border, image.cols, image.rows));
}

// Differing pixels between ours (both paths) and OpenCV's, for one image and size.
void expect_as_opencv(const cv::Mat& image, cv::Size to, const std::string& what) {
  cv::Mat reference;
  cv::resize(image, reference, to, 0, 0, cv::INTER_LINEAR);
  LinearResize resize(image.size(), to);
  const cv::Mat source = framed_view(image, 19);
  for (const bool avx2 : {true, false}) {
    cv::Mat ours;
    resize(source, ours, avx2);
    ASSERT_EQ(ours.size(), to);
    EXPECT_EQ(cv::countNonZero(ours != reference), 0)
        << what << " " << image.size() << " -> " << to << (avx2 ? " (AVX2 path)" : " (plain path)");
  }
}

// The pyramid's sizes: each level from the one before, by 1.2.
std::vector<cv::Size> pyramid_sizes(cv::Size size, int levels) {
  std::vector<cv::Size> sizes{size};
  double scale = 1.0;
  for (int l = 1; l < levels; ++l) {
    scale *= 1.2;
    const float inv = static_cast<float>(1.0 / scale);
    sizes.emplace_back(cvRound(static_cast<float>(size.width) * inv), cvRound(static_cast<float>(size.height) * inv));
  }
  return sizes;
}

TEST(LinearResize, EqualsOpenCvAlongThePyramidOnBothPaths) {
  const cv::Mat frame = test::render_machine_hall_frame(0.4);
  const std::vector<cv::Size> sizes = pyramid_sizes(frame.size(), 8);
  cv::Mat level = frame, noise = noise_image(frame.size(), 3);
  for (std::size_t l = 1; l < sizes.size(); ++l) {
    expect_as_opencv(level, sizes[l], "rendered frame, level " + std::to_string(l));
    expect_as_opencv(noise, sizes[l], "noise, level " + std::to_string(l));
    cv::resize(level, level, sizes[l], 0, 0, cv::INTER_LINEAR);
    cv::resize(noise, noise, sizes[l], 0, 0, cv::INTER_LINEAR);
  }
}

TEST(LinearResize, EqualsOpenCvForOtherSizesShrinkingAndGrowing) {
  for (int width = 1; width <= 70; width += 3)
    for (const int to : {1, 5, width / 2 + 1, (width * 5) / 6 + 1, width + 7, 2 * width + 3})
      expect_as_opencv(noise_image({width, 11}, static_cast<unsigned>(width)), {to, 9}, "noise");
  for (const cv::Size from : {cv::Size(640, 480), cv::Size(1280, 720), cv::Size(511, 17)})
    for (const cv::Size to : {cv::Size(533, 400), cv::Size(from.width / 3, from.height / 3 + 1)})
      expect_as_opencv(noise_image(from, 9), to, "camera size");
  cv::Mat saturated = noise_image({90, 40}, 5);
  saturated(cv::Rect(20, 10, 60, 20)).setTo(255);
  saturated(cv::Rect(0, 0, 10, 40)).setTo(0);
  expect_as_opencv(saturated, {75, 33}, "saturated patch");
}

TEST(LinearResize, RefusesOtherTypesAndSizes) {
  LinearResize resize({40, 30}, {33, 25});
  cv::Mat out;
  EXPECT_THROW(resize(cv::Mat(30, 40, CV_16UC1), out), Error);
  EXPECT_THROW(resize(cv::Mat(31, 40, CV_8UC1), out), Error);
  cv::Mat same(25, 33, CV_8UC1);
  EXPECT_THROW(LinearResize({33, 25}, {33, 25})(same, same), Error);  // in place
  EXPECT_THROW(LinearResize({0, 25}, {33, 25}), Error);
}

}  // namespace
}  // namespace orbatlas
