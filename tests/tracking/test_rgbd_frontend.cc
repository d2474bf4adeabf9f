// The RGB-D front end on a rendered Machine Hall frame with its
// depth image from the simulated depth camera: every keypoint with depth has
// the depth the renderer drew along its (undistorted) ray, and the virtual
// right coordinate u - bf / depth; bad input gets a clear error.
#include <gtest/gtest.h>

#include <algorithm>

#include "core/camera/camera_factory.h"
#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/io/settings.h"
#include "core/sim/depth_sensor.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/machine_hall.h"
#include "core/sim/renderer.h"
#include "core/sim/trajectory_spline.h"
#include "core/tracking/frame_frontend.h"
#include "core/tracking/rgbd_frontend.h"

namespace orbatlas {
namespace {

TEST(RgbdFrontend, KeypointsGetTheRenderedDepthAndAVirtualRightCoordinate) {
  const SlamSettings settings = read_settings(shipped_config_dir() / "euroc" / "rgbd.yaml");
  sim::MachineHallOptions hall;
  hall.texel_size_m = 0.01;  // quick to build
  const sim::World world = sim::build_machine_hall(sim::load_machine_hall_trajectories(), hall);
  const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  const Pose3 T_w_c = spline.pose(spline.start_ns() + 40 * kNsPerSecond) * settings.camera0.T_b_c;
  const auto cam0 = make_camera(settings.camera0);
  sim::Renderer renderer(world, *cam0);
  cv::Mat image;
  renderer.render(T_w_c, image, 1);
  sim::DepthSensorOptions exact;
  exact.noise_per_m2 = 0.0;
  const cv::Mat depth = sim::DepthSensor(*cam0, exact).measure(renderer, 1);

  const auto frontend = make_frame_frontend(settings);
  const Frame f = frontend->make_frame(77, image, depth);
  const double bf = frontend->frame_camera().bf;
  EXPECT_NEAR(bf, 0.08 * settings.camera0.fx, 1e-9);
  EXPECT_TRUE(std::all_of(frontend->calibration().distortion.begin(), frontend->calibration().distortion.end(),
                          [](double d) { return d == 0.0; }));
  std::size_t with_depth = 0;
  std::vector<double> errors;
  const Camera& pinhole = *frontend->frame_camera().camera;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.depth[i] <= 0.0f) continue;
    ++with_depth;
    EXPECT_NEAR(f.u_right[i], f.features.keypoints[i].uv.x() - bf / f.depth[i], 1e-3);
    // The rendered depth along the keypoint's ray (through the undistorted camera).
    const Eigen::Vector3d ray = pinhole.unproject(f.features.keypoints[i].uv.cast<double>());
    if (const auto truth = renderer.depth_along(ray)) errors.push_back(std::abs(f.depth[i] - *truth) / *truth);
  }
  ASSERT_GT(errors.size(), 100u);
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2], p95 = errors[errors.size() * 95 / 100];
  EXPECT_GE(f.size(), 900u);
  EXPECT_GT(with_depth, f.size() / 2);
  // Measured: median 1.9e-5, 95th percentile 5.6e-3 (keypoints next to a depth edge).
  EXPECT_LT(median, 5e-5);
  EXPECT_LT(p95, 1.2e-2);

  EXPECT_THROW(frontend->make_frame(78, image, cv::Mat()), DataError);  // no depth
  EXPECT_THROW(frontend->make_frame(78, image, image), DataError);      // 8-bit: not a depth image
  EXPECT_THROW(frontend->make_frame(78, image, depth(cv::Rect(0, 0, 100, 100))), DataError);  // another size
  // A single camera's front end: no depth, one image per frame.
  const auto mono = make_frame_frontend(read_settings(shipped_config_dir() / "euroc" / "mono.yaml"));
  EXPECT_EQ(mono->baseline(), 0.0);
  EXPECT_EQ(mono->frame_camera().bf, 0.0);
  EXPECT_THROW(mono->make_frame(78, image, image), DataError);
}

}  // namespace
}  // namespace orbatlas
