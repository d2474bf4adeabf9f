// The simulated depth camera (`orbatlas sim --depth`) against exact
// geometry: a tilted wall seen through the distorted EuRoC cam0 reads, at
// every pixel up to the image corners, the depth of that pixel's ray; the
// noise has the sigma asked for; a depth edge leaves holes; depths out of range
// are absent; a simulated sequence reads back as a TUM RGB-D dataset.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include <opencv2/core.hpp>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/io/tum_rgbd.h"
#include "core/sim/depth_sensor.h"
#include "core/sim/renderer.h"
#include "core/sim/sequence_simulator.h"
#include "core/sim/world.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

int plain_texture(sim::World& world) {
  sim::TextureRequest req;
  req.width_m = req.height_m = 40.0;
  req.texel_size_m = 0.02;
  return world.add_texture(sim::make_texture(req));
}

// The wall z = 4 + 0.5 x (camera frame, the camera at the origin looking along z).
double wall_depth(const Eigen::Vector3d& ray) { return 4.0 / (1.0 - 0.5 * ray.x() / ray.z()); }

void add_wall(sim::World& world) {
  sim::Quad q;
  const Eigen::Vector3d u = Eigen::Vector3d(1.0, 0.0, 0.5).normalized() * 40.0;
  q.edge_u = u;
  q.edge_v = Eigen::Vector3d(0.0, 40.0, 0.0);
  q.origin = Eigen::Vector3d(0.0, 0.0, 4.0) - 0.5 * q.edge_u - 0.5 * q.edge_v;
  q.texture = plain_texture(world);
  world.add_quad(q);
}

TEST(DepthSensor, EveryPixelReadsTheDepthOfItsRay) {
  const auto camera = make_camera(test::euroc_cam0());
  sim::World world;
  add_wall(world);
  sim::Renderer renderer(world, *camera);
  cv::Mat image;
  renderer.render(Pose3(), image, 1);
  sim::DepthSensorOptions o;
  o.noise_per_m2 = 0.0;
  const sim::DepthSensor sensor(*camera, o);
  const cv::Mat exact = sensor.exact(renderer), measured = sensor.measure(renderer, 7);
  ASSERT_EQ(measured.type(), CV_16UC1);
  double worst = 0.0, worst_corner = 0.0;
  int checked = 0, holes = 0;
  for (int v = 0; v < exact.rows; ++v)
    for (int u = 0; u < exact.cols; ++u) {
      const double truth = wall_depth(camera->unproject(Eigen::Vector2d(u, v)));
      const double z = exact.at<float>(v, u);
      if (z <= 0.0) continue;
      ++checked;
      // The renderer's z-buffer is sampled at the nearest canvas pixel: its step sets the bound.
      worst = std::max(worst, std::abs(z - truth) / truth);
      if (u < 40 && v < 40) worst_corner = std::max(worst_corner, std::abs(z - truth) / truth);
      const std::uint16_t value = measured.at<std::uint16_t>(v, u);
      if (value == 0) {
        ++holes;
        continue;
      }
      EXPECT_NEAR(value / o.depth_map_factor, z, 0.5 / o.depth_map_factor + 1e-6);
    }
  EXPECT_GT(checked, exact.rows * exact.cols * 9 / 10);
  EXPECT_LT(worst, 4e-3);
  EXPECT_LT(worst_corner, 1e-3);     // measured 4.6e-4 (1.6e-3 overall)
  EXPECT_LT(holes, checked / 1000);  // a smooth wall has no edge
}

// A board 2 m away in front of the wall at 4 m: the pixels on its outline
// have no depth; 1.425e-3 z^2 of noise at 4 m (2.3 cm) is what is measured;
// with the range cut at 3 m only the board remains.
TEST(DepthSensor, NoiseEdgesAndRange) {
  const auto camera = make_camera(test::euroc_cam0());
  sim::World world;
  sim::Quad wall;
  wall.edge_u = Eigen::Vector3d(40.0, 0.0, 0.0);
  wall.edge_v = Eigen::Vector3d(0.0, 40.0, 0.0);
  wall.origin = Eigen::Vector3d(-20.0, -20.0, 4.0);
  wall.texture = plain_texture(world);
  world.add_quad(wall);
  sim::Quad board = wall;
  board.edge_u = Eigen::Vector3d(1.0, 0.0, 0.0);
  board.edge_v = Eigen::Vector3d(0.0, 1.0, 0.0);
  board.origin = Eigen::Vector3d(-0.5, -0.5, 2.0);
  world.add_quad(board);
  sim::Renderer renderer(world, *camera);
  cv::Mat image;
  renderer.render(Pose3(), image, 1);

  const sim::DepthSensor noisy(*camera);
  const cv::Mat exact = noisy.exact(renderer), measured = noisy.measure(renderer, 11);
  double sum = 0.0, sum2 = 0.0;
  int wall_pixels = 0, edge_holes = 0;
  for (int v = 1; v + 1 < exact.rows; ++v)
    for (int u = 1; u + 1 < exact.cols; ++u) {
      const float z = exact.at<float>(v, u);
      const bool at_edge =
          std::abs(exact.at<float>(v, u - 1) - z) > 0.5f || std::abs(exact.at<float>(v, u + 1) - z) > 0.5f;
      if (at_edge) {
        edge_holes += measured.at<std::uint16_t>(v, u) == 0;
        continue;
      }
      if (std::abs(z - 4.0f) > 0.01f || measured.at<std::uint16_t>(v, u) == 0) continue;
      const double e = measured.at<std::uint16_t>(v, u) / 5000.0 - z;
      sum += e;
      sum2 += e * e;
      ++wall_pixels;
    }
  const double mean = sum / wall_pixels, sigma = std::sqrt(sum2 / wall_pixels - mean * mean);
  EXPECT_NEAR(sigma, 1.425e-3 * 16.0, 0.02 * 1.425e-3 * 16.0);
  EXPECT_LT(std::abs(mean), 3.0 * sigma / std::sqrt(wall_pixels));
  EXPECT_GT(edge_holes, 4 * 200);  // the board's outline: about 4 x 230 pixels

  sim::DepthSensorOptions near;
  near.max_range_m = 3.0;
  const cv::Mat board_only = sim::DepthSensor(*camera, near).measure(renderer, 11);
  int far_values = 0, board_values = 0;
  for (int v = 0; v < board_only.rows; ++v)
    for (int u = 0; u < board_only.cols; ++u) {
      const std::uint16_t d = board_only.at<std::uint16_t>(v, u);
      if (d == 0) continue;
      (d > 3.0 * 5000.0 ? far_values : board_values) += 1;
    }
  EXPECT_EQ(far_values, 0);
  EXPECT_GT(board_values, 30000);  // 1 m at 2 m: about 230 x 230 pixels

  sim::DepthSensorOptions bad;
  bad.max_range_m = 20.0;  // 100000 at 5000 per metre: not 16-bit
  EXPECT_THROW(sim::DepthSensor(*camera, bad), Error);
}

TEST(DepthSensor, ASimulatedSequenceReadsBackAsTumRgbd) {
  const auto out = std::filesystem::temp_directory_path() / ("orbatlas_sim_depth_" + std::to_string(getpid()));
  std::filesystem::remove_all(out);
  sim::SimulationOptions o;
  o.sequence = "MH_01";
  o.out_dir = out;
  o.start_s = 40.0;
  o.duration_s = 0.5;
  o.show_progress = false;
  o.depth = sim::DepthSensorOptions{};
  const sim::SimulationReport report = sim::simulate_sequence(o);
  EXPECT_EQ(report.depth_images, report.frames);
  const TumRgbdDataset d = read_tum_rgbd(out);
  EXPECT_EQ(d.frames.size(), report.frames);
  EXPECT_EQ(d.unpaired, 0u);
  EXPECT_GT(d.ground_truth.size(), 90u);  // 200 Hz body poses over 0.5 s
  const cv::Mat depth = read_depth_image(d.frames.front().depth, 752, 480);
  const int valid = cv::countNonZero(depth);
  EXPECT_GT(valid, depth.rows * depth.cols / 4);
  std::filesystem::remove_all(out);
}

}  // namespace
}  // namespace orbatlas
