// Stereo depth on rendered pairs against the exact depth of the scene.
#include <gtest/gtest.h>

#include <iostream>

#include <algorithm>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/features/keypoint_geometry.h"
#include "core/features/orb_extractor.h"
#include "core/features/patch_sad.h"
#include "core/features/remap_bilinear.h"
#include "core/features/stereo_rectified.h"
#include "core/features/stereo_triangulated.h"
#include "core/sim/renderer.h"
#include "core/sim/world.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

// A textured wall perpendicular to the left camera's optical axis at `depth`.
sim::World wall_world(const Pose3& T_w_c0, double depth) {
  sim::World world;
  sim::TextureRequest req;
  req.width_m = req.height_m = 12.0;
  req.texel_size_m = 0.004;
  req.seed = 11;
  const int tex = world.add_texture(sim::make_texture(req));
  sim::Quad q;
  const Eigen::Matrix3d R = T_w_c0.rotation();
  q.edge_u = R.col(0) * 12.0;
  q.edge_v = R.col(1) * 12.0;
  q.origin = T_w_c0 * Eigen::Vector3d(-6.0, -6.0, depth);
  q.texture = tex;
  world.add_quad(q);
  return world;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// True depth (z in the camera frame `T_w_c`) of the wall along a bearing.
double wall_depth_along(const Pose3& T_w_c, const Eigen::Vector3d& bearing_c, const Pose3& T_w_c0, double depth) {
  const Eigen::Vector3d n_w = T_w_c0.rotation().col(2);
  const Eigen::Vector3d p0 = T_w_c0 * Eigen::Vector3d(0, 0, depth);
  const Eigen::Vector3d d_w = T_w_c.q * bearing_c;
  const double s = n_w.dot(p0 - T_w_c.t) / n_w.dot(d_w);
  return (s * bearing_c).z();
}

class RectifiedStereoDepth : public ::testing::TestWithParam<double> {};

TEST_P(RectifiedStereoDepth, MedianDepthErrorBelowOnePercent) {
  const double depth = GetParam();
  const CameraCalibration c0 = test::euroc_cam0(), c1 = test::euroc_cam1();
  const Pose3 T_w_b(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 1));
  const Pose3 T_w_c0 = T_w_b * c0.T_b_c, T_w_c1 = T_w_b * c1.T_b_c;
  const sim::World world = wall_world(T_w_c0, depth);
  const auto cam0 = make_camera(c0), cam1 = make_camera(c1);
  sim::Renderer r0(world, *cam0), r1(world, *cam1);
  cv::Mat left, right, left_rect, right_rect;
  r0.render(T_w_c0, left, 1);
  r1.render(T_w_c1, right, 2);

  const StereoRectifier rectifier(c0, c1);
  EXPECT_NEAR(rectifier.baseline(), 0.110, 0.001);
  rectifier.rectify(left, right, left_rect, right_rect);
  OrbExtractor ex_left({}), ex_right({});
  ImageFeatures fl = ex_left.extract(left_rect), fr = ex_right.extract(right_rect);
  const StereoDepths depths = match_stereo_rectified(fl, ex_left.pyramid(), fr, ex_right.pyramid(),
                                                     ex_left.scale_factors(), rectifier.bf(), rectifier.baseline());
  const auto rect_cam = make_camera(rectifier.rectified_left());
  compute_keypoint_geometry(*rect_cam, fl.keypoints);
  const Pose3 T_w_rect = T_w_b * rectifier.rectified_left().T_b_c;
  std::vector<double> rel_errors, coarse_right_errors;
  for (std::size_t i = 0; i < fl.keypoints.size(); ++i) {
    if (depths.depth[i] <= 0) continue;
    const double truth = wall_depth_along(T_w_rect, fl.keypoints[i].bearing, T_w_c0, depth);
    rel_errors.push_back(std::abs(depths.depth[i] - truth) / truth);
    // The right coordinate carries the match's disparity from the keypoint's own
    // position, also for a keypoint of a coarser level that sits between pixels.
    const double u_left = fl.keypoints[i].uv.x();
    EXPECT_NEAR(u_left - depths.u_right[i], rectifier.bf() / depths.depth[i], 1e-3);
    if (fl.keypoints[i].level > 0)
      coarse_right_errors.push_back(std::abs(depths.u_right[i] - (u_left - rectifier.bf() / truth)));
  }
  ASSERT_GT(rel_errors.size(), fl.keypoints.size() / 3);
  EXPECT_LT(median(rel_errors), 0.01);
  ASSERT_GT(coarse_right_errors.size(), 100u);
  std::cout << depth << " m: right coordinate of coarser levels' keypoints off by " << median(coarse_right_errors)
            << " px (median)\n";
  EXPECT_LT(median(coarse_right_errors), 0.15);  // measured 0.073 (2 m), 0.033 px (5 m)
  // Outlier rejection keeps gross errors rare.
  const auto gross = std::count_if(rel_errors.begin(), rel_errors.end(), [](double e) { return e > 0.1; });
  EXPECT_LT(static_cast<double>(gross), 0.02 * static_cast<double>(rel_errors.size()));
}

INSTANTIATE_TEST_SUITE_P(Depths, RectifiedStereoDepth, ::testing::Values(2.0, 5.0));

TEST(RectifiedStereo, RejectsMismatchedImagesAndFisheye) {
  const StereoRectifier rectifier(test::euroc_cam0(), test::euroc_cam1());
  cv::Mat small(100, 100, CV_8UC1, cv::Scalar(0)), a, b;
  EXPECT_THROW(rectifier.rectify(small, small, a, b), Error);
  EXPECT_THROW(StereoRectifier(test::fisheye_left(), test::fisheye_right()), Error);
}

// The rectifier keeps remap's fixed-point maps (converted once) instead of
// float maps (converted by remap on every image): the images are the same.
TEST(RectifiedStereo, FixedPointMapsRectifyAsTheFloatMapsDo) {
  const CameraCalibration left = test::euroc_cam0(), right = test::euroc_cam1();
  const StereoRectifier rectifier(left, right);
  cv::Mat image(left.height, left.width, CV_8UC1);
  cv::randu(image, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.0);
  cv::Mat left_rect, right_rect;
  rectifier.rectify(image, image, left_rect, right_rect);
  // The float maps of the same rectification.
  const Pose3 T_c1_c0 = right.T_b_c.inverse() * left.T_b_c;
  const auto K = [](const CameraCalibration& c) -> cv::Mat {
    return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
  };
  cv::Mat R1, R2, P1, P2, Q, R(3, 3, CV_64F);
  const Eigen::Matrix3d rotation = T_c1_c0.rotation();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R.at<double>(r, c) = rotation(r, c);
  const cv::Mat T = (cv::Mat_<double>(3, 1) << T_c1_c0.t.x(), T_c1_c0.t.y(), T_c1_c0.t.z());
  const cv::Size size(left.width, left.height);
  cv::stereoRectify(K(left), cv::Mat(left.distortion), K(right), cv::Mat(right.distortion), size, R, T, R1, R2, P1, P2,
                    Q, cv::CALIB_ZERO_DISPARITY, 0);
  cv::Mat map_x, map_y, expected;
  cv::initUndistortRectifyMap(K(left), cv::Mat(left.distortion), R1, P1, size, CV_32F, map_x, map_y);
  cv::remap(image, expected, map_x, map_y, cv::INTER_LINEAR);
  EXPECT_EQ(cv::norm(left_rect, expected, cv::NORM_INF), 0.0);
  cv::initUndistortRectifyMap(K(right), cv::Mat(right.distortion), R2, P2, size, CV_32F, map_x, map_y);
  cv::remap(image, expected, map_x, map_y, cv::INTER_LINEAR);
  EXPECT_EQ(cv::norm(right_rect, expected, cv::NORM_INF), 0.0);
}

// The own remap is cv::remap's result bit for bit (INTER_LINEAR, fixed-point
// maps, constant border 0), with and without its AVX2 paths (byte shuffles
// within a window of three rows, gathers, and single pixels at the edges):
// maps that reach past every edge (zoomed out, shifted, jittered, turned),
// widths that are not whole vectors, and a source that is a view of a larger image.
TEST(RemapBilinear, EqualsCvRemapBitForBitAlsoAtTheBorders) {
  cv::RNG rng(7);
  for (const cv::Size size : {cv::Size(752, 480), cv::Size(37, 23), cv::Size(9, 2)}) {
    cv::Mat whole(size.height + 6, size.width + 10, CV_8UC1);
    cv::randu(whole, 0, 256);
    const cv::Mat src = whole(cv::Rect(3, 2, size.width, size.height));  // not continuous
    for (int kind = 0; kind < 4; ++kind) {
      cv::Mat map_x(size, CV_32F), map_y(size, CV_32F);
      for (int y = 0; y < size.height; ++y)
        for (int x = 0; x < size.width; ++x) {
          const float cx = 0.5f * static_cast<float>(size.width), cy = 0.5f * static_cast<float>(size.height);
          float u = static_cast<float>(x), v = static_cast<float>(y);
          if (kind == 0) u = cx + 1.15f * (u - cx) + 0.3f, v = cy + 1.15f * (v - cy) - 0.7f;  // past every edge
          if (kind == 1) u += 2.5f, v -= 1.25f;                                               // shifted
          if (kind == 2) u += rng.uniform(-4.0f, 4.0f), v += rng.uniform(-4.0f, 4.0f);        // jittered
          if (kind == 3) {  // turned a little and barrel-distorted, as a rectification: rows cross within blocks
            const float du = u - cx, dv = v - cy, k = 1.0f + 0.05f * (du * du + dv * dv) / (cx * cx);
            u = cx + (0.9996f * du - 0.03f * dv) * k, v = cy + (0.03f * du + 0.9996f * dv) * k;
          }
          map_x.at<float>(y, x) = u;
          map_y.at<float>(y, x) = v;
        }
      cv::Mat xy, frac, expected;
      cv::convertMaps(map_x, map_y, xy, frac, CV_16SC2);
      cv::remap(src, expected, xy, frac, cv::INTER_LINEAR);
      for (const bool avx2 : {true, false}) {
        cv::Mat mine;
        remap_bilinear(src, mine, xy, frac, avx2);
        ASSERT_EQ(mine.size(), expected.size());
        EXPECT_EQ(cv::norm(mine, expected, cv::NORM_INF), 0.0)
            << size << " map kind " << kind << (avx2 ? " (AVX2)" : " (scalar)");
      }
    }
  }
  cv::Mat xy(4, 4, CV_16SC2, cv::Scalar(0, 0)), frac(4, 4, CV_16UC1, cv::Scalar(0)), out;
  EXPECT_THROW(remap_bilinear(cv::Mat(4, 4, CV_16UC1), out, xy, frac), Error);   // not 8-bit
  EXPECT_THROW(remap_bilinear(cv::Mat(4, 4, CV_8UC1), out, frac, frac), Error);  // not a CV_16SC2 map
  EXPECT_THROW(remap_bilinear(cv::Mat(4, 4, CV_8UC1), out, xy, frac(cv::Rect(0, 0, 2, 2))), Error);  // sizes differ
}

// The row search's zero-mean SADs (left patch and right sums computed once
// per row) are exactly those of one zero_mean_sad per offset, on random
// images and for the window sizes and ranges stereo matching uses.
TEST(RectifiedStereo, TheRowSadSearchGivesEveryOffsetsZeroMeanSad) {
  cv::Mat a(60, 120, CV_8UC1), b(60, 120, CV_8UC1);
  cv::randu(a, 0, 256);
  cv::randu(b, 0, 256);
  std::size_t compared = 0;
  // The AVX2 path (where the CPU has it) and the portable loop; ranges up to
  // past the 16 offsets the AVX2 path takes at once (range 9: 19 offsets).
  for (const bool avx2 : {true, false}) {
    RowSadSearch search;
    search.set_use_avx2(avx2);
    std::vector<int> sads;
    for (const int w : {1, 3, 5})
      for (const int range : {0, 2, 7, 9}) {
        const int ua = 40, va = 30, ub0 = 60;
        search.run(a, ua, va, b, ub0, range, w, sads);
        ASSERT_EQ(sads.size(), static_cast<std::size_t>(2 * range + 1));
        for (int k = -range; k <= range; ++k, ++compared)
          EXPECT_EQ(sads[static_cast<std::size_t>(k + range)], zero_mean_sad(a, ua, va, b, ub0 + k, va, w))
              << "w " << w << " offset " << k << (avx2 ? " (AVX2 path)" : " (portable)");
      }
  }
  EXPECT_EQ(compared, 2u * 3u * (1 + 5 + 15 + 19));
}

TEST(TriangulatedStereo, FisheyeDepthAtFiveMetres) {
  const double depth = 5.0;
  const CameraCalibration c0 = test::fisheye_left(), c1 = test::fisheye_right();
  const Pose3 T_w_b(Eigen::Quaterniond(Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(0, 1, 1));
  const Pose3 T_w_c0 = T_w_b * c0.T_b_c, T_w_c1 = T_w_b * c1.T_b_c;
  const sim::World world = wall_world(T_w_c0, depth);
  const auto cam0 = make_camera(c0), cam1 = make_camera(c1);
  sim::Renderer r0(world, *cam0), r1(world, *cam1);
  cv::Mat left, right;
  r0.render(T_w_c0, left, 1);
  r1.render(T_w_c1, right, 2);
  OrbExtractor ex_left({}), ex_right({});
  ImageFeatures fl = ex_left.extract(left), fr = ex_right.extract(right);
  compute_keypoint_geometry(*cam0, fl.keypoints);
  compute_keypoint_geometry(*cam1, fr.keypoints);
  const TriangulatedStereo st =
      match_stereo_triangulated(*cam0, fl, *cam1, fr, T_w_c0.inverse() * T_w_c1, ex_left.level_sigma2(), left, right);
  std::vector<double> rel_errors;
  for (std::size_t i = 0; i < fl.keypoints.size(); ++i) {
    if (st.right_index[i] < 0) continue;
    const double truth = wall_depth_along(T_w_c0, fl.keypoints[i].bearing, T_w_c0, depth);
    rel_errors.push_back(std::abs(st.depth[i] - truth) / truth);
  }
  ASSERT_GT(rel_errors.size(), 200u);
  EXPECT_LT(median(rel_errors), 0.01);
}

TEST(TriangulatedStereo, RaysMeetAtTheirCommonPoint) {
  const Eigen::Vector3d p(0.3, -0.2, 4.0), o2(0.11, 0.0, 0.0);
  Eigen::Vector3d out;
  ASSERT_TRUE(triangulate_rays(Eigen::Vector3d::Zero(), p.normalized(), o2, (p - o2).normalized(), &out));
  EXPECT_LT((out - p).norm(), 1e-9);
  EXPECT_FALSE(triangulate_rays(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), o2, Eigen::Vector3d::UnitZ(), &out));
  EXPECT_FALSE(triangulate_rays(Eigen::Vector3d::Zero(), -p.normalized(), o2, -(p - o2).normalized(), &out))
      << "behind";
}

}  // namespace
}  // namespace orbatlas
