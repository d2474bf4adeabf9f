// Camera models against their own inverses, numeric differentiation, OpenCV
// (cv::projectPoints, cv::fisheye::projectPoints) and ceres::Jet autodiff.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <random>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/camera/kannala_brandt.h"
#include "core/camera/pinhole_radtan.h"
#include "core/common/error.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

constexpr double kPi = 3.14159265358979323846;

using test::euroc_cam0;

CameraCalibration euroc_cam0_k3() {
  CameraCalibration c = euroc_cam0();
  c.distortion.push_back(0.012);
  return c;
}

// EuRoC-size fisheye (ORB-SLAM3's KannalaBrandt8 example calibration).
CameraCalibration fisheye() { return test::fisheye_left(); }

std::vector<CameraCalibration> all_calibrations() { return {euroc_cam0(), euroc_cam0_k3(), fisheye()}; }

// Every 8 px over the whole image, plus the last row and column (so all four corners).
std::vector<Eigen::Vector2d> image_grid(int width, int height) {
  std::vector<int> us, vs;
  for (int u = 0; u < width; u += 8) us.push_back(u);
  if (us.back() != width - 1) us.push_back(width - 1);
  for (int v = 0; v < height; v += 8) vs.push_back(v);
  if (vs.back() != height - 1) vs.push_back(height - 1);
  std::vector<Eigen::Vector2d> grid;
  for (int v : vs) {
    for (int u : us) grid.emplace_back(u, v);
  }
  return grid;
}

// Random points in front of the camera whose pixels fall in or near the image:
// normalised coordinates up to `max_xy`, depth 0.2..30 m.
std::vector<Eigen::Vector3d> points_in_front(std::mt19937* rng, int n, double max_x, double max_y) {
  std::uniform_real_distribution<double> ux(-max_x, max_x), uy(-max_y, max_y), depth(0.2, 30.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double z = depth(*rng);
    points.emplace_back(ux(*rng) * z, uy(*rng) * z, z);
  }
  return points;
}

// Random points at angle 0..max_theta from the optical axis, range 0.2..30 m.
std::vector<Eigen::Vector3d> points_by_angle(std::mt19937* rng, int n, double max_theta) {
  std::uniform_real_distribution<double> theta(0.0, max_theta), phi(0.0, 2 * kPi), range(0.2, 30.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double t = theta(*rng), f = phi(*rng), r = range(*rng);
    points.emplace_back(r * std::sin(t) * std::cos(f), r * std::sin(t) * std::sin(f), r * std::cos(t));
  }
  return points;
}

std::vector<Eigen::Vector3d> test_points(const Camera& camera, std::mt19937* rng, int n) {
  if (camera.model() == CameraModel::kKannalaBrandt) return points_by_angle(rng, n, 1.5);
  return points_in_front(rng, n, 1.2, 0.8);
}

TEST(Camera, UnprojectThenProjectOverWholeImage) {
  for (const CameraCalibration& calibration : all_calibrations()) {
    SCOPED_TRACE(camera_model_name(calibration.model));
    const auto camera = make_camera(calibration);
    const auto grid = image_grid(camera->width(), camera->height());
    ASSERT_EQ(grid.size(), 95u * 61u);
    double worst = 0.0;
    for (const Eigen::Vector2d& uv : grid) {
      const Eigen::Vector3d bearing = camera->unproject(uv);
      ASSERT_NEAR(bearing.norm(), 1.0, 1e-12);
      Eigen::Vector2d back;
      ASSERT_TRUE(camera->project(bearing, &back)) << "pixel " << uv.transpose();
      worst = std::max(worst, (back - uv).norm());
      EXPECT_LT((back - uv).norm(), 1e-6) << "pixel " << uv.transpose();
    }
    // The corners of the EuRoC image are well inside the models' valid range.
    EXPECT_LT(worst, 1e-6);
  }
}

TEST(Camera, ProjectThenUnprojectGivesTheBearing) {
  std::mt19937 rng(7);
  for (const CameraCalibration& calibration : all_calibrations()) {
    SCOPED_TRACE(camera_model_name(calibration.model));
    const auto camera = make_camera(calibration);
    for (const Eigen::Vector3d& p : test_points(*camera, &rng, 2000)) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(camera->project(p, &uv)) << p.transpose();
      const Eigen::Vector3d bearing = camera->unproject(uv);
      EXPECT_LT((bearing - p.normalized()).norm(), 1e-9) << p.transpose();
    }
  }
}

TEST(Camera, FisheyeRoundTripBeyondNinetyDegrees) {
  const KannalaBrandt camera(fisheye());
  EXPECT_GT(camera.max_theta(), 0.5 * kPi) << camera.max_theta();
  EXPECT_LT(camera.max_theta(), kPi);
  std::mt19937 rng(11);
  for (const Eigen::Vector3d& p : points_by_angle(&rng, 500, camera.max_theta() - 0.05)) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.project(p, &uv));
    EXPECT_LT((camera.unproject(uv) - p.normalized()).norm(), 1e-9) << p.transpose();
  }
}

TEST(Camera, AnalyticJacobianMatchesCentralDifferences) {
  std::mt19937 rng(3);
  for (const CameraCalibration& calibration : all_calibrations()) {
    SCOPED_TRACE(camera_model_name(calibration.model));
    const auto camera = make_camera(calibration);
    auto points = test_points(*camera, &rng, 1000);
    points.emplace_back(0.0, 0.0, 2.0);       // on the optical axis
    points.emplace_back(1e-13, -2e-13, 1.0);  // next to it
    points.emplace_back(0.3, -0.2, 0.05);     // close, far off-axis
    for (const Eigen::Vector3d& p : points) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(camera->project(p, &uv));
      const Eigen::Matrix<double, 2, 3> analytic = camera->project_jacobian(p);
      Eigen::Matrix<double, 2, 3> numeric;
      const double h = 1e-5 * p.norm();
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector3d plus = p, minus = p;
        plus[k] += h;
        minus[k] -= h;
        Eigen::Vector2d up, um;
        ASSERT_TRUE(camera->project(plus, &up));
        ASSERT_TRUE(camera->project(minus, &um));
        numeric.col(k) = (up - um) / (2 * h);
      }
      const double scale = analytic.cwiseAbs().maxCoeff();
      EXPECT_LE((analytic - numeric).cwiseAbs().maxCoeff(), 1e-6 * scale) << "at " << p.transpose() << "\nanalytic\n"
                                                                          << analytic << "\nnumeric\n"
                                                                          << numeric;
    }
  }
}

TEST(Camera, JetProjectionMatchesProjectAndJacobian) {
  using Jet = ceres::Jet<double, 3>;
  std::mt19937 rng(5);
  const PinholeRadTan pinhole(euroc_cam0_k3());
  const KannalaBrandt fish(fisheye());
  const auto check = [](const auto& camera, const Eigen::Vector3d& p) {
    const Jet pj[3] = {Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2)};
    Jet uvj[2];
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.project(p, &uv));
    ASSERT_TRUE(camera.project_t(pj, uvj));
    const Eigen::Matrix<double, 2, 3> j = camera.project_jacobian(p);
    for (int r = 0; r < 2; ++r) {
      EXPECT_NEAR(uvj[r].a, uv[r], 1e-9);
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(uvj[r].v[c], j(r, c), 1e-9 * j.cwiseAbs().maxCoeff());
    }
  };
  for (const Eigen::Vector3d& p : points_in_front(&rng, 300, 1.2, 0.8)) check(pinhole, p);
  for (const Eigen::Vector3d& p : points_by_angle(&rng, 300, fish.max_theta() - 0.05)) check(fish, p);
  check(fish, Eigen::Vector3d(0.0, 0.0, 1.5));  // the optical axis: no NaN from sqrt(0)
  // Jets reject what project() rejects.
  const Jet behind[3] = {Jet(0.1), Jet(0.2), Jet(-1.0)};
  Jet out[2];
  EXPECT_FALSE(pinhole.project_t(behind, out));
}

TEST(Camera, PinholeMatchesOpenCvProjectPoints) {
  std::mt19937 rng(1);
  for (const CameraCalibration& calibration : {euroc_cam0(), euroc_cam0_k3()}) {
    SCOPED_TRACE(calibration.distortion.size());
    const auto camera = make_camera(calibration);
    const auto points = points_in_front(&rng, 3000, 1.3, 0.9);
    std::vector<cv::Point3d> object;
    for (const Eigen::Vector3d& p : points) object.emplace_back(p.x(), p.y(), p.z());
    const cv::Matx33d k(calibration.fx, 0, calibration.cx, 0, calibration.fy, calibration.cy, 0, 0, 1);
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, calibration.distortion, image);
    ASSERT_EQ(image.size(), points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(camera->project(points[i], &uv));
      EXPECT_NEAR(uv.x(), image[i].x, 1e-6);
      EXPECT_NEAR(uv.y(), image[i].y, 1e-6);
    }
  }
}

TEST(Camera, FisheyeMatchesOpenCvFisheyeProjectPoints) {
  std::mt19937 rng(2);
  const CameraCalibration calibration = fisheye();
  const auto camera = make_camera(calibration);
  const auto points = points_by_angle(&rng, 3000, 1.45);  // OpenCV's fisheye needs z > 0
  std::vector<cv::Point3d> object;
  for (const Eigen::Vector3d& p : points) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d k(calibration.fx, 0, calibration.cx, 0, calibration.fy, calibration.cy, 0, 0, 1);
  const cv::Vec4d d(calibration.distortion[0], calibration.distortion[1], calibration.distortion[2],
                    calibration.distortion[3]);
  std::vector<cv::Point2d> image;
  cv::fisheye::projectPoints(object, image, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k, d);
  ASSERT_EQ(image.size(), points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera->project(points[i], &uv));
    EXPECT_NEAR(uv.x(), image[i].x, 1e-6);
    EXPECT_NEAR(uv.y(), image[i].y, 1e-6);
  }
}

TEST(Camera, PinholeRejectsPointsBehindOrOnThePlane) {
  const auto camera = make_camera(euroc_cam0());
  Eigen::Vector2d uv;
  EXPECT_FALSE(camera->project(Eigen::Vector3d(0.1, 0.2, -1.0), &uv));
  EXPECT_FALSE(camera->project(Eigen::Vector3d(0.0, 0.0, -1e-3), &uv));
  EXPECT_FALSE(camera->project(Eigen::Vector3d(1.0, 1.0, 0.0), &uv));
  EXPECT_FALSE(camera->project(Eigen::Vector3d(0.0, 0.0, 0.0), &uv));
  EXPECT_FALSE(camera->project(Eigen::Vector3d(0.0, 0.0, std::numeric_limits<double>::quiet_NaN()), &uv));
  EXPECT_TRUE(camera->project(Eigen::Vector3d(0.0, 0.0, 1e-3), &uv));
  EXPECT_NEAR(uv.x(), 367.215, 1e-9);
  EXPECT_NEAR(uv.y(), 248.375, 1e-9);
}

TEST(Camera, PinholeRejectsPointsWhereTheDistortionFoldsBack) {
  CameraCalibration c = euroc_cam0();
  EXPECT_EQ(PinholeRadTan(c).max_r2(), std::numeric_limits<double>::infinity());
  c.distortion = {-0.5, 0.0, 0.0, 0.0};  // r (1 - 0.5 r^2) peaks at r^2 = 2/3
  const PinholeRadTan camera(c);
  EXPECT_NEAR(camera.max_r2(), 2.0 / 3.0, 1e-9);
  Eigen::Vector2d uv;
  EXPECT_TRUE(camera.project(Eigen::Vector3d(0.8, 0.0, 1.0), &uv));
  EXPECT_FALSE(camera.project(Eigen::Vector3d(0.9, 0.0, 1.0), &uv));
}

TEST(Camera, FisheyeRejectsZeroAndBeyondItsValidAngle) {
  const KannalaBrandt camera(fisheye());
  Eigen::Vector2d uv;
  EXPECT_FALSE(camera.project(Eigen::Vector3d::Zero(), &uv));
  EXPECT_FALSE(camera.project(Eigen::Vector3d(0.0, 0.0, -1.0), &uv));
  const double beyond = camera.max_theta() + 0.01;
  EXPECT_FALSE(camera.project(Eigen::Vector3d(std::sin(beyond), 0.0, std::cos(beyond)), &uv));
  const double inside = camera.max_theta() - 0.01;
  EXPECT_TRUE(camera.project(Eigen::Vector3d(std::sin(inside), 0.0, std::cos(inside)), &uv));
  EXPECT_TRUE(camera.project(Eigen::Vector3d(1.0, 0.0, 0.0), &uv));  // 90 degrees: fine for a fisheye
  EXPECT_TRUE(camera.project(Eigen::Vector3d(0.0, 0.0, 1.0), &uv));
  EXPECT_NEAR(uv.x(), 380.573, 1e-12);
  EXPECT_NEAR(uv.y(), 225.950, 1e-12);
}

TEST(Camera, MakeCameraRejectsBadCalibrations) {
  const auto expect_error = [](CameraCalibration c, const std::string& expected) {
    try {
      (void)make_camera(c);
      ADD_FAILURE() << "no error, expected one about " << expected;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  CameraCalibration c = euroc_cam0();
  c.fx = 0;
  expect_error(c, "fx");
  c = euroc_cam0();
  c.fy = -450;
  expect_error(c, "fy");
  c = euroc_cam0();
  c.cx = std::numeric_limits<double>::quiet_NaN();
  expect_error(c, "cx");
  c = euroc_cam0();
  c.width = 0;
  expect_error(c, "size");
  c = euroc_cam0();
  c.height = -480;
  expect_error(c, "size");
  c = euroc_cam0();
  c.distortion = {0.1, 0.2, 0.3};
  expect_error(c, "4 or 5 distortion coefficients");
  c.distortion = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  expect_error(c, "4 or 5 distortion coefficients");
  c = fisheye();
  c.distortion = {0.1, 0.2, 0.3, 0.4, 0.5};
  expect_error(c, "4 distortion coefficients");
  c = fisheye();
  c.distortion = {};
  expect_error(c, "4 distortion coefficients");
  c = fisheye();
  c.distortion[2] = std::numeric_limits<double>::infinity();
  expect_error(c, "not finite");
  // The constructors apply the same checks.
  c = euroc_cam0();
  c.fx = -1;
  EXPECT_THROW(PinholeRadTan{c}, Error);
  c = fisheye();
  c.distortion.pop_back();
  EXPECT_THROW(KannalaBrandt{c}, Error);
}

TEST(Camera, FactoryBuildsTheModelAndKeepsTheCalibration) {
  CameraCalibration c = fisheye();
  c.T_b_c = Pose3(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(1, 2, 3));
  const auto camera = make_camera(c);
  EXPECT_EQ(camera->model(), CameraModel::kKannalaBrandt);
  EXPECT_EQ(camera->width(), 752);
  EXPECT_EQ(camera->height(), 480);
  const CameraCalibration back = camera->calibration();
  EXPECT_EQ(back.distortion, c.distortion);
  EXPECT_EQ(back.fx, c.fx);
  EXPECT_EQ(back.rate_hz, c.rate_hz);
  EXPECT_TRUE(back.T_b_c.t.isApprox(c.T_b_c.t));
  EXPECT_EQ(make_camera(euroc_cam0_k3())->calibration().distortion.size(), 5u);
  EXPECT_EQ(make_camera(euroc_cam0())->model(), CameraModel::kPinholeRadTan);
  EXPECT_STREQ(camera_model_name(CameraModel::kPinholeRadTan), "pinhole-radtan");
  EXPECT_STREQ(camera_model_name(CameraModel::kKannalaBrandt), "kannala-brandt");
}

TEST(Camera, InImageUsesPixelCentres) {
  const auto camera = make_camera(euroc_cam0());
  EXPECT_TRUE(camera->in_image({0.0, 0.0}));
  EXPECT_TRUE(camera->in_image({751.0, 479.0}));
  EXPECT_FALSE(camera->in_image({-0.01, 10.0}));
  EXPECT_FALSE(camera->in_image({751.01, 10.0}));
  EXPECT_FALSE(camera->in_image({10.0, 479.01}));
  EXPECT_FALSE(camera->in_image({10.0, 5.0}, 8.0));
  EXPECT_TRUE(camera->in_image({8.0, 8.0}, 8.0));
  EXPECT_TRUE(camera->in_image({743.0, 471.0}, 8.0));
  EXPECT_FALSE(camera->in_image({743.5, 100.0}, 8.0));
}

}  // namespace
}  // namespace orbatlas
