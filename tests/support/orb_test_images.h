#pragma once
// What the ORB extractor tests share: a rendered Machine Hall frame, noise
// images, and the checks every extraction must pass (the requested count, the
// keypoints' levels, angles, responses and borders).
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/features/orb_extractor.h"
#include "tests/support/rendered_frames.h"

namespace orbatlas::test {

// Built once per test program.
inline const cv::Mat& rendered_frame() {
  static const cv::Mat image = render_machine_hall_frame(0.4);
  return image;
}

inline cv::Mat noise_image(int width, int height, std::uint32_t seed) {
  cv::Mat image(height, width, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> grey(0, 255);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) image.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(grey(rng));
  return image;
}

// The count ORB-SLAM's quadtree gives is not exact. Per level it stops splitting
// as soon as the node count reaches the level's share, and the last split adds
// up to 3 nodes to at most share - 1: at most 2 more per level. It gives fewer
// when a level has fewer FAST corners than its share, or when a splitting pass
// separates no corners. We accept [98%, +2 per level] of the request.
inline void expect_count_near_request(std::size_t count, const OrbExtractorOptions& options, const std::string& what) {
  EXPECT_GE(static_cast<double>(count), 0.98 * options.n_features) << what;
  EXPECT_LE(static_cast<int>(count), options.n_features + 2 * options.n_levels) << what;
}

inline void expect_valid_features(const ImageFeatures& f, const OrbExtractor& extractor, const cv::Mat& image) {
  ASSERT_EQ(f.descriptors.size(), f.keypoints.size());
  EXPECT_EQ(f.width, image.cols);
  EXPECT_EQ(f.height, image.rows);
  std::vector<int> per_level(static_cast<std::size_t>(extractor.options().n_levels), 0);
  for (const Keypoint& kp : f.keypoints) {
    ASSERT_GE(kp.level, 0);
    ASSERT_LT(kp.level, extractor.options().n_levels);
    ++per_level[static_cast<std::size_t>(kp.level)];
    EXPECT_GE(kp.angle_deg, 0.0f);
    EXPECT_LT(kp.angle_deg, 360.0f);
    EXPECT_GE(kp.response, static_cast<float>(extractor.options().min_th_fast));
    // Keypoints keep the descriptor patch inside the level image.
    const Eigen::Vector2f ratio = extractor.level_ratios()[static_cast<std::size_t>(kp.level)];
    const cv::Mat& level = extractor.pyramid()[static_cast<std::size_t>(kp.level)];
    const float x = level_coordinate(kp.uv.x(), ratio.x()), y = level_coordinate(kp.uv.y(), ratio.y());
    EXPECT_GE(x, OrbExtractor::kPyramidBorder - 1e-3f);
    EXPECT_GE(y, OrbExtractor::kPyramidBorder - 1e-3f);
    EXPECT_LT(x, static_cast<float>(level.cols - OrbExtractor::kPyramidBorder));
    EXPECT_LT(y, static_cast<float>(level.rows - OrbExtractor::kPyramidBorder));
  }
  // Every level holds keypoints, and none more than its share + 2 (the quadtree's overshoot).
  for (std::size_t l = 0; l < per_level.size(); ++l) {
    EXPECT_GT(per_level[l], 0) << "level " << l;
    EXPECT_LE(per_level[l], extractor.features_per_level()[l] + 2) << "level " << l;
  }
}

}  // namespace orbatlas::test
