// The renderer against exact geometry: markers appear where the camera model
// projects them, depth is exact, and stereo disparity gives the known depth.
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera/camera_factory.h"
#include "core/sim/renderer.h"
#include "core/sim/world.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

using sim::Quad;
using sim::World;

// A bright Gaussian spot on a dark square: no hard edge, so its centroid is not
// disturbed by the pixel grid and measures the projection geometry alone.
int spot_texture(World& world, double size_m) {
  sim::Texture tex;
  tex.texel_size_m = size_m / 64.0;
  cv::Mat img(64, 64, CV_8UC1);
  for (int v = 0; v < 64; ++v)
    for (int u = 0; u < 64; ++u) {
      const double r2 = (std::pow(u - 31.5, 2) + std::pow(v - 31.5, 2)) / (10.0 * 10.0);
      img.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(30 + 220 * std::exp(-0.5 * r2));
    }
  tex.levels.push_back(img);
  sim::build_mipmaps(tex);
  return world.add_texture(tex);
}

int uniform_texture(World& world, std::uint8_t value) {
  sim::TextureRequest req;
  req.style = sim::TextureStyle::kUniform;
  req.uniform_value = value;
  req.width_m = req.height_m = 0.1;
  return world.add_texture(sim::make_texture(req));
}

// A square of side `size` centred at p_w, facing the camera at T_w_c.
Quad facing_square(const Eigen::Vector3d& p_w, double size, const Pose3& T_w_c, int texture) {
  const Eigen::Matrix3d R = T_w_c.rotation();
  Quad q;
  q.edge_u = R.col(0) * size;
  q.edge_v = R.col(1) * size;
  q.origin = p_w - 0.5 * q.edge_u - 0.5 * q.edge_v;
  q.texture = texture;
  return q;
}

// Intensity-weighted centroid of pixels above the threshold in a window.
Eigen::Vector2d bright_centroid(const cv::Mat& img, const Eigen::Vector2d& around, int radius, int threshold) {
  double sx = 0, sy = 0, sw = 0;
  for (int v = std::max(0, static_cast<int>(around.y()) - radius);
       v <= std::min(img.rows - 1, static_cast<int>(around.y()) + radius); ++v)
    for (int u = std::max(0, static_cast<int>(around.x()) - radius);
         u <= std::min(img.cols - 1, static_cast<int>(around.x()) + radius); ++u) {
      const int w = img.at<std::uint8_t>(v, u) - threshold;
      if (w <= 0) continue;
      sx += w * u;
      sy += w * v;
      sw += w;
    }
  EXPECT_GT(sw, 0.0) << "marker not visible near " << around.transpose();
  return sw > 0 ? Eigen::Vector2d(sx / sw, sy / sw) : Eigen::Vector2d(-1, -1);
}

TEST(Renderer, MarkerAppearsWhereTheCameraProjectsIt) {
  const auto camera = make_camera(test::euroc_cam0());
  const Pose3 T_w_c(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
                    Eigen::Vector3d(1, 2, 3));
  World world;
  const int dark = uniform_texture(world, 30), white = spot_texture(world, 0.064);
  // Backdrop far behind the markers.
  world.add_quad(facing_square(T_w_c * Eigen::Vector3d(0, 0, 20), 200.0, T_w_c, dark));
  // Markers over the whole image, corners included (strongest distortion).
  std::vector<Eigen::Vector2d> targets;
  for (const double u : {30.0, 200.0, 376.0, 600.0, 722.0})
    for (const double v : {25.0, 240.0, 455.0}) targets.emplace_back(u, v);
  std::vector<Eigen::Vector3d> points_w;
  for (const auto& uv : targets) {
    const Eigen::Vector3d p_c = camera->unproject(uv) * 4.0;
    points_w.push_back(T_w_c * p_c);
    world.add_quad(facing_square(points_w.back(), 0.064, T_w_c, white));
  }
  sim::RenderOptions options;
  options.noise_sigma = 0.0;
  sim::Renderer renderer(world, *camera, options);
  cv::Mat image;
  renderer.render(T_w_c, image, 1);
  ASSERT_EQ(image.cols, 752);
  ASSERT_EQ(image.rows, 480);
  for (std::size_t i = 0; i < targets.size(); ++i) {
    Eigen::Vector2d expected;
    ASSERT_TRUE(camera->project(T_w_c.inverse() * points_w[i], &expected));
    const Eigen::Vector2d found = bright_centroid(image, expected, 16, 36);
    EXPECT_LT((found - expected).norm(), 0.25)
        << "marker " << i << " expected " << expected.transpose() << " found " << found.transpose();
  }
}

TEST(Renderer, DepthOfAFrontoParallelPlaneIsExact) {
  const auto camera = make_camera(test::euroc_cam0());
  const Pose3 T_w_c;
  World world;
  sim::TextureRequest req;
  req.width_m = req.height_m = 40.0;
  req.texel_size_m = 0.02;
  sim::Quad q = facing_square(Eigen::Vector3d(0, 0, 4.0), 40.0, T_w_c, world.add_texture(sim::make_texture(req)));
  world.add_quad(q);
  sim::Renderer renderer(world, *camera);
  cv::Mat image;
  renderer.render(T_w_c, image, 1);
  const cv::Mat& depth = renderer.canvas_depth();
  int checked = 0;
  for (int v = 0; v < depth.rows; v += 7)
    for (int u = 0; u < depth.cols; u += 7) {
      const float z = depth.at<float>(v, u);
      if (!std::isfinite(z)) continue;
      EXPECT_NEAR(z, 4.0, 1e-4);
      ++checked;
    }
  EXPECT_GT(checked, 5000);
  // The image is textured, not flat: a feature-rich surface.
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev);
  EXPECT_GT(stddev[0], 20.0);
}

TEST(Renderer, StereoDisparityMatchesKnownDepth) {
  const CameraCalibration c0 = test::euroc_cam0(), c1 = test::euroc_cam1();
  const auto cam0 = make_camera(c0), cam1 = make_camera(c1);
  const Pose3 T_w_b(Eigen::Quaterniond(Eigen::AngleAxisd(-0.4, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(2, -1, 1));
  const Pose3 T_w_c0 = T_w_b * c0.T_b_c, T_w_c1 = T_w_b * c1.T_b_c;
  const Pose3 T_c1_c0 = T_w_c1.inverse() * T_w_c0;

  // Rectification of the pair, as a stereo front end would do it.
  cv::Mat K0 = (cv::Mat_<double>(3, 3) << c0.fx, 0, c0.cx, 0, c0.fy, c0.cy, 0, 0, 1);
  cv::Mat K1 = (cv::Mat_<double>(3, 3) << c1.fx, 0, c1.cx, 0, c1.fy, c1.cy, 0, 0, 1);
  cv::Mat D0(c0.distortion), D1(c1.distortion);
  cv::Mat R, T, R0, R1, P0, P1, Q;
  const Eigen::Matrix3d r = T_c1_c0.rotation();
  cv::Mat(3, 3, CV_64F, const_cast<double*>(Eigen::Matrix3d(r.transpose()).data()))
      .copyTo(R);  // Eigen col-major -> row-major
  T = (cv::Mat_<double>(3, 1) << T_c1_c0.t.x(), T_c1_c0.t.y(), T_c1_c0.t.z());
  cv::stereoRectify(K0, D0, K1, D1, cv::Size(752, 480), R, T, R0, R1, P0, P1, Q, cv::CALIB_ZERO_DISPARITY, 0);
  const double f = P0.at<double>(0, 0), baseline = -P1.at<double>(0, 3) / P1.at<double>(0, 0);
  ASSERT_NEAR(baseline, 0.110, 0.002);
  Eigen::Matrix3d R0e;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R0e(i, j) = R0.at<double>(i, j);

  World world;
  const int dark = uniform_texture(world, 30);
  world.add_quad(facing_square(T_w_c0 * Eigen::Vector3d(0, 0, 30), 300.0, T_w_c0, dark));
  std::vector<Eigen::Vector3d> markers_c0 = {{-0.6, -0.3, 2.0}, {0.3, 0.2, 3.0}, {0.0, -0.2, 5.0}, {0.8, 0.4, 4.0}};
  for (const auto& p : markers_c0)
    world.add_quad(facing_square(T_w_c0 * p, 0.032 * p.z(), T_w_c0, spot_texture(world, 0.032 * p.z())));
  sim::RenderOptions options;
  options.noise_sigma = 0.0;
  sim::Renderer r0(world, *cam0, options), r1(world, *cam1, options);
  cv::Mat left, right;
  r0.render(T_w_c0, left, 1);
  r1.render(T_w_c1, right, 2);

  for (const auto& p_c0 : markers_c0) {
    Eigen::Vector2d uv0, uv1;
    ASSERT_TRUE(cam0->project(p_c0, &uv0));
    ASSERT_TRUE(cam1->project(T_c1_c0 * p_c0, &uv1));
    const Eigen::Vector2d m0 = bright_centroid(left, uv0, 20, 36), m1 = bright_centroid(right, uv1, 20, 36);
    std::vector<cv::Point2d> in0{{m0.x(), m0.y()}}, in1{{m1.x(), m1.y()}}, out0, out1;
    cv::undistortPoints(in0, out0, K0, D0, R0, P0);
    cv::undistortPoints(in1, out1, K1, D1, R1, P1);
    const double disparity = out0[0].x - out1[0].x;
    const double depth = f * baseline / disparity;
    const double true_depth = (R0e * p_c0).z();
    EXPECT_NEAR(depth / true_depth, 1.0, 0.01) << "marker at " << p_c0.transpose() << ": disparity " << disparity;
    EXPECT_NEAR(out0[0].y, out1[0].y, 0.3) << "rows differ after rectification: " << out0[0].y << " vs " << out1[0].y;
  }
}

}  // namespace
}  // namespace orbatlas
