// Matching utilities: the feature grid against brute force, the rotation
// histogram, brute-force and guided matching of a rendered frame against itself
// turned by 30 degrees, and the ratio test on constructed descriptors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/features/feature_grid.h"
#include "core/features/matching.h"
#include "core/features/orb_extractor.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/rendered_frames.h"

namespace orbatlas {
namespace {

const cv::Mat& rendered_frame() {
  static const cv::Mat image = test::render_machine_hall_frame(0.4);  // built once for the whole file
  return image;
}

Keypoint keypoint_at(float u, float v, int level = 0, float angle = 0.0f) {
  Keypoint kp;
  kp.uv = Eigen::Vector2f(u, v);
  kp.level = level;
  kp.angle_deg = angle;
  return kp;
}

Descriptor with_bits_flipped(Descriptor d, int first, int count) {
  for (int b = first; b < first + count; ++b) d[static_cast<std::size_t>(b / 64)] ^= std::uint64_t{1} << (b % 64);
  return d;
}

TEST(FeatureGrid, RadiusSearchEqualsBruteForce) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-10.0f, 762.0f), v(-10.0f, 490.0f), r(0.0f, 120.0f);
  std::uniform_int_distribution<int> level(0, 7), bound(-1, 7);
  ImageFeatures f;
  f.width = 752;
  f.height = 480;
  for (int i = 0; i < 3000; ++i) f.keypoints.push_back(keypoint_at(u(rng), v(rng), level(rng)));
  const FeatureGrid grid(f);
  EXPECT_EQ(grid.size(), f.keypoints.size());
  std::size_t found_total = 0;
  std::vector<std::size_t> reused;
  for (int q = 0; q < 1000; ++q) {
    const Eigen::Vector2f c(u(rng) * 1.1f - 30.0f, v(rng) * 1.1f - 30.0f);  // some queries outside the image
    const float radius = q % 10 == 0 ? 0.0f : r(rng);
    int lo = bound(rng), hi = bound(rng);
    if (q % 3 == 0) lo = hi = -1;
    std::vector<std::size_t> expected;
    for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
      const Keypoint& kp = f.keypoints[i];
      if ((lo >= 0 && kp.level < lo) || (hi >= 0 && kp.level > hi)) continue;
      const float du = kp.uv.x() - c.x(), dv = kp.uv.y() - c.y();
      if (du * du + dv * dv <= radius * radius) expected.push_back(i);
    }
    std::vector<std::size_t> got = grid.in_radius(c, radius, lo, hi);
    grid.in_radius(c, radius, lo, hi, reused);
    EXPECT_EQ(reused, got);
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got, expected) << "query " << q << " at " << c.transpose() << " radius " << radius << " levels " << lo
                             << ".." << hi;
    found_total += got.size();
  }
  EXPECT_GT(found_total, 10000u);  // the queries did find things
}

TEST(FeatureGrid, EdgeCases) {
  const FeatureGrid empty;
  EXPECT_TRUE(empty.in_radius(Eigen::Vector2f(10, 10), 100.0f).empty());
  ImageFeatures f;
  f.keypoints.push_back(keypoint_at(5, 5));
  EXPECT_THROW(FeatureGrid{f}, Error);  // no image size
  f.width = 100;
  f.height = 50;
  f.keypoints.push_back(keypoint_at(std::numeric_limits<float>::quiet_NaN(), 5));
  const FeatureGrid grid(f, 10, 5);
  EXPECT_EQ(grid.size(), 1u);  // the NaN position is left out
  EXPECT_EQ(grid.in_radius(Eigen::Vector2f(5, 5), 0.0f), std::vector<std::size_t>{0});
  EXPECT_TRUE(grid.in_radius(Eigen::Vector2f(5, 5), -1.0f).empty());
  EXPECT_TRUE(grid.in_radius(Eigen::Vector2f(std::numeric_limits<float>::quiet_NaN(), 5), 10.0f).empty());
  EXPECT_TRUE(grid.in_radius(Eigen::Vector2f(5, 5), 10.0f, 1).empty());  // level 0 is below min_level 1
  EXPECT_THROW(FeatureGrid(f, 0, 5), Error);
}

TEST(RotationHistogram, KeepsTheThreeMostPopulatedBins) {
  EXPECT_EQ(RotationHistogram::bin_of(0.0f), 0);
  EXPECT_EQ(RotationHistogram::bin_of(5.9f), 0);
  EXPECT_EQ(RotationHistogram::bin_of(-5.9f), 0);
  EXPECT_EQ(RotationHistogram::bin_of(354.1f), 0);
  EXPECT_EQ(RotationHistogram::bin_of(-7.0f), 29);
  EXPECT_EQ(RotationHistogram::bin_of(30.5f), 3);
  EXPECT_EQ(RotationHistogram::bin_of(29.0f), 2);
  EXPECT_EQ(RotationHistogram::bin_of(390.0f + 360.0f), 3);
  EXPECT_FLOAT_EQ(RotationHistogram::bin_center_deg(3), 36.0f);

  RotationHistogram h;
  EXPECT_EQ(h.top_bins(), (std::array<int, 3>{-1, -1, -1}));
  std::size_t index = 0;
  std::vector<std::size_t> expected_outliers;
  const auto add = [&](float angle, int n, bool outlier) {
    for (int i = 0; i < n; ++i) {
      if (outlier) expected_outliers.push_back(index);
      h.add(angle + 0.1f * static_cast<float>(i % 3), index++);
    }
  };
  add(24.0f, 50, false);  // bin 2
  add(96.0f, 20, false);  // bin 8
  add(-12.0f, 6, false);  // bin 29
  add(204.0f, 3, true);   // bin 17
  add(300.0f, 1, true);   // bin 25
  EXPECT_EQ(h.count(2), 50);
  EXPECT_EQ(h.top_bins(), (std::array<int, 3>{2, 8, 29}));
  std::vector<std::size_t> outliers = h.outliers();
  std::sort(outliers.begin(), outliers.end());
  EXPECT_EQ(outliers, expected_outliers);

  // The second and third bins count only with at least 10% of the first.
  RotationHistogram g;
  for (std::size_t i = 0; i < 100; ++i) g.add(0.0f, i);
  for (std::size_t i = 100; i < 110; ++i) g.add(60.0f, i);   // 10%: kept
  for (std::size_t i = 110; i < 119; ++i) g.add(120.0f, i);  // 9%: dropped
  EXPECT_EQ(g.top_bins(), (std::array<int, 3>{0, 5, -1}));
  EXPECT_EQ(g.outliers().size(), 9u);
  g.clear();
  EXPECT_EQ(g.count(0), 0);
}

TEST(Matching, RatioTestRejectsAmbiguousMatches) {
  BestTwo t;
  EXPECT_FALSE(t.accept(100, 0.8f));  // nothing added
  t.add(4, 10);
  EXPECT_TRUE(t.accept(100, 0.8f));  // no second candidate
  EXPECT_FALSE(t.accept(9, 0.8f));   // above the distance threshold
  t.add(7, 11);
  EXPECT_EQ(t.index, 4u);
  EXPECT_EQ(t.second, 11);
  EXPECT_FALSE(t.accept(100, 0.8f));  // 10 vs 11: ambiguous
  t.add(9, 9);
  EXPECT_EQ(t.index, 9u);
  EXPECT_EQ(t.best, 9);
  EXPECT_EQ(t.second, 10);

  std::mt19937_64 rng(5);
  const auto random_descriptor = [&] { return Descriptor{rng(), rng(), rng(), rng()}; };
  ImageFeatures a, b;
  a.width = b.width = 752;
  a.height = b.height = 480;
  const Descriptor d0 = random_descriptor(), d1 = random_descriptor(), d2 = random_descriptor();
  a.descriptors = {d0, d1, d2};
  a.keypoints = {keypoint_at(100, 100), keypoint_at(200, 200), keypoint_at(300, 300)};
  // d0: two near-equal candidates (10 and 11 bits away). d1: one clear candidate.
  // d2: the same b as d1 but farther, so it loses that b.
  b.descriptors = {with_bits_flipped(d0, 0, 10), with_bits_flipped(d0, 100, 11), with_bits_flipped(d1, 30, 5),
                   random_descriptor()};
  b.keypoints = {keypoint_at(100, 100), keypoint_at(110, 100), keypoint_at(200, 200), keypoint_at(400, 400)};
  a.descriptors[2] = with_bits_flipped(d1, 200, 12);
  const std::vector<FeatureMatch> m = match_brute_force(a, b);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].a, 1u);
  EXPECT_EQ(m[0].b, 2u);
  EXPECT_EQ(m[0].distance, 5);
  // A looser ratio accepts the ambiguous one.
  BruteForceMatchOptions loose;
  loose.ratio = 0.95f;
  const std::vector<FeatureMatch> m2 = match_brute_force(a, b, loose);
  ASSERT_EQ(m2.size(), 2u);
  EXPECT_EQ(m2[0].a, 0u);
  EXPECT_EQ(m2[0].b, 0u);
}

TEST(Matching, GuidedSearchRespectsRadiusAndLevels) {
  std::mt19937_64 rng(8);
  const auto random_descriptor = [&] { return Descriptor{rng(), rng(), rng(), rng()}; };
  ImageFeatures a, b;
  a.width = b.width = 752;
  a.height = b.height = 480;
  const Descriptor d = random_descriptor(), e = random_descriptor();
  a.keypoints = {keypoint_at(100, 100, 0), keypoint_at(300, 300, 2)};
  a.descriptors = {d, e};
  b.keypoints = {keypoint_at(400, 100, 0),   // exact copy of d, far from the prediction
                 keypoint_at(104, 102, 0),   // d with 20 bits flipped, near it
                 keypoint_at(305, 300, 5),   // e, near but three levels away
                 keypoint_at(300, 310, 3)};  // e with 8 bits flipped, near, one level away
  b.descriptors = {d, with_bits_flipped(d, 0, 20), e, with_bits_flipped(e, 50, 8)};
  const FeatureGrid grid(b);
  const std::vector<Eigen::Vector2f> predicted = {Eigen::Vector2f(100, 100), Eigen::Vector2f(300, 300)};
  const std::vector<FeatureMatch> m = match_guided(a, predicted, b, grid);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0].b, 1u);
  EXPECT_EQ(m[0].distance, 20);
  EXPECT_EQ(m[1].b, 3u);
  // Any level: the exact copy at level 5 wins.
  GuidedMatchOptions any;
  any.level_window = -1;
  EXPECT_EQ(match_guided(a, predicted, b, grid, any)[1].b, 2u);
  // A NaN prediction skips the keypoint; a wrong number of predictions throws.
  const std::vector<Eigen::Vector2f> partial = {Eigen::Vector2f(std::nanf(""), 0), Eigen::Vector2f(300, 300)};
  const std::vector<FeatureMatch> m3 = match_guided(a, partial, b, grid);
  ASSERT_EQ(m3.size(), 1u);
  EXPECT_EQ(m3[0].a, 1u);
  EXPECT_THROW(match_guided(a, {Eigen::Vector2f(0, 0)}, b, grid), Error);
}

// The frame against itself turned 30 degrees counter-clockwise about its centre.
class RotatedFrame : public ::testing::Test {
 protected:
  void SetUp() override {
    const cv::Mat& image = rendered_frame();
    rotation_ = cv::getRotationMatrix2D(cv::Point2f(375.5f, 239.5f), 30.0, 1.0);
    cv::Mat rotated;
    cv::warpAffine(image, rotated, rotation_, image.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    OrbExtractor extractor({});
    a_ = extractor.extract(image);
    b_ = extractor.extract(rotated);
  }

  Eigen::Vector2f rotated(const Eigen::Vector2f& uv) const {
    const auto m = [&](int r, int c) { return static_cast<float>(rotation_.at<double>(r, c)); };
    return {m(0, 0) * uv.x() + m(0, 1) * uv.y() + m(0, 2), m(1, 0) * uv.x() + m(1, 1) * uv.y() + m(1, 2)};
  }

  double fraction_correct(const std::vector<FeatureMatch>& matches) const {
    int correct = 0;
    for (const FeatureMatch& m : matches)
      if ((b_.keypoints[m.b].uv - rotated(a_.keypoints[m.a].uv)).norm() < 2.0f) ++correct;
    return matches.empty() ? 0.0 : static_cast<double>(correct) / static_cast<double>(matches.size());
  }

  cv::Mat rotation_;
  ImageFeatures a_, b_;
};

TEST_F(RotatedFrame, BruteForceMatchesLandOnTheRotatedPositions) {
  BruteForceMatchOptions no_check;
  no_check.check_orientation = false;
  const std::vector<FeatureMatch> raw = match_brute_force(a_, b_, no_check);
  ASSERT_GT(raw.size(), 300u);
  // The rotation histogram of the raw matches peaks at 30 degrees: 30 lies on the
  // edge between bins 2 (24) and 3 (36), which together hold most matches.
  RotationHistogram h;
  double sum = 0;
  int near = 0;
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const float diff = a_.keypoints[raw[i].a].angle_deg - b_.keypoints[raw[i].b].angle_deg;
    h.add(diff, i);
    const double wrapped = std::remainder(static_cast<double>(diff) - 30.0, 360.0);
    if (std::abs(wrapped) < 12.0) {
      sum += wrapped;
      ++near;
    }
  }
  const std::array<int, 3> top = h.top_bins();
  EXPECT_TRUE(top[0] == 2 || top[0] == 3) << "peak bin " << top[0];
  EXPECT_GT(h.count(2) + h.count(3), static_cast<int>(0.7 * static_cast<double>(raw.size())));
  EXPECT_NEAR(sum / near, 0.0, 1.0) << "mean orientation change " << 30.0 + sum / near;

  const std::vector<FeatureMatch> checked = match_brute_force(a_, b_);
  const double correct = fraction_correct(checked);
  EXPECT_GT(checked.size(), 300u);
  EXPECT_GT(correct, 0.8);
  EXPECT_GE(fraction_correct(checked), fraction_correct(raw));
}

TEST_F(RotatedFrame, GuidedMatchesAroundPredictions) {
  std::vector<Eigen::Vector2f> predicted;
  for (const Keypoint& kp : a_.keypoints) predicted.push_back(rotated(kp.uv));
  const FeatureGrid grid(b_);
  const std::vector<FeatureMatch> m = match_guided(a_, predicted, b_, grid);
  const double correct = fraction_correct(m);
  EXPECT_GT(m.size(), 400u);
  EXPECT_GT(correct, 0.9);
}

}  // namespace
}  // namespace orbatlas
