// PreloadedPairs: pairs pushed come back in order, pixel for pixel, whatever
// their layout; errors and single images survive; the buffers are reused.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "core/io/preloaded_pairs.h"

namespace orbatlas {
namespace {

cv::Mat random_image(int rows, int cols, int type, cv::RNG& rng) {
  cv::Mat m(rows, cols, type);
  rng.fill(m, cv::RNG::UNIFORM, 0, type == CV_16UC1 ? 65536 : 256);
  return m;
}

bool same(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty()) return a.empty() && b.empty();
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(PreloadedPairs, PairsComeBackInOrderPixelForPixel) {
  cv::RNG rng(7);
  std::vector<LoadedFrame> pushed;
  // A stereo pair; a grey image with its 16-bit depth (RGB-D); a left image
  // alone (a single camera); a pair cut out of larger images (not continuous);
  // a pair that could not be read (its error, no images); another stereo pair.
  pushed.push_back({100, random_image(480, 752, CV_8UC1, rng), random_image(480, 752, CV_8UC1, rng), ""});
  pushed.push_back({200, random_image(480, 640, CV_8UC1, rng), random_image(480, 640, CV_16UC1, rng), ""});
  pushed.push_back({300, random_image(240, 320, CV_8UC1, rng), cv::Mat(), ""});
  const cv::Mat big = random_image(500, 800, CV_8UC1, rng);
  pushed.push_back({400, big(cv::Rect(3, 5, 752, 480)), big(cv::Rect(40, 10, 752, 480)), ""});
  pushed.push_back({500, cv::Mat(), cv::Mat(), "cam1/data/500.png: cannot be read"});
  pushed.push_back({600, random_image(480, 752, CV_8UC1, rng), random_image(480, 752, CV_8UC1, rng), ""});
  ASSERT_FALSE(pushed[3].left.isContinuous());

  PreloadedPairs preloaded;
  for (const LoadedFrame& p : pushed) preloaded.push(p);
  EXPECT_EQ(preloaded.size(), pushed.size());
  EXPECT_EQ(preloaded.bytes(), 2u * 480 * 752 + 480 * 640 * 3 + 240 * 320 + 2u * 480 * 752 + 2u * 480 * 752);

  for (std::size_t i = 0; i < pushed.size(); ++i) {
    const auto p = preloaded.pop();
    ASSERT_TRUE(p.has_value()) << i;
    EXPECT_EQ(p->t_ns, pushed[i].t_ns) << i;
    EXPECT_EQ(p->error, pushed[i].error) << i;
    EXPECT_TRUE(same(p->left, pushed[i].left)) << i;
    EXPECT_TRUE(same(p->right, pushed[i].right)) << i;
    EXPECT_EQ(preloaded.size(), pushed.size() - i - 1);
  }
  EXPECT_FALSE(preloaded.pop().has_value());
  EXPECT_FALSE(preloaded.pop().has_value());
}

TEST(PreloadedPairs, PairsOfOneShapeShareTheTwoBuffers) {
  cv::RNG rng(11);
  PreloadedPairs preloaded;
  const LoadedFrame a{1, random_image(48, 64, CV_8UC1, rng), random_image(48, 64, CV_8UC1, rng), ""};
  const LoadedFrame b{2, random_image(48, 64, CV_8UC1, rng), random_image(48, 64, CV_8UC1, rng), ""};
  preloaded.push(a);
  preloaded.push(b);
  const auto first = preloaded.pop();
  const uchar* left_pixels = first->left.data;
  EXPECT_TRUE(same(first->left, a.left));
  const auto second = preloaded.pop();
  // No allocation per pair: the second pair's images are read into the same
  // memory, which is why a pair is valid only until the next pop().
  EXPECT_EQ(second->left.data, left_pixels);
  EXPECT_TRUE(same(second->left, b.left));
  EXPECT_TRUE(same(second->right, b.right));
}

}  // namespace
}  // namespace orbatlas
