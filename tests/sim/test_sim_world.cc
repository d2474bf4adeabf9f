// The Machine Hall world: deterministic, shared by all sequences, and it keeps
// every trajectory free.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "core/sim/machine_hall.h"

namespace orbatlas {
namespace {

// Distance from a point to a quad (a rectangle).
double distance_to_quad(const Eigen::Vector3d& p, const sim::Quad& q) {
  const Eigen::Vector3d d = p - q.origin;
  const double a = std::clamp(d.dot(q.edge_u) / q.edge_u.squaredNorm(), 0.0, 1.0);
  const double b = std::clamp(d.dot(q.edge_v) / q.edge_v.squaredNorm(), 0.0, 1.0);
  return (q.origin + a * q.edge_u + b * q.edge_v - p).norm();
}

Trajectory line_trajectory(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  Trajectory t;
  for (int i = 0; i <= 400; ++i)
    t.push_back({i * 5'000'000LL, Pose3(Eigen::Quaterniond::Identity(), from + (to - from) * i / 400.0)});
  return t;
}

TEST(MachineHall, KeepsTrajectoriesClearAndIsDeterministic) {
  const std::vector<Trajectory> paths = {line_trajectory({0, 0, 0}, {8, 3, 1}),
                                         line_trajectory({2, 6, 0.5}, {6, -2, 0.5})};
  sim::MachineHallOptions options;
  options.seed = 5;
  options.machine_count = 30;
  options.texel_size_m = 0.02;  // small textures keep the test fast
  sim::HallBounds bounds;
  const sim::World world = sim::build_machine_hall(paths, options, &bounds);
  ASSERT_GT(world.quads().size(), 6u + 30u * 5u - 1u) << "hall + machines expected";
  for (std::size_t i = 6; i < world.quads().size(); ++i)
    for (const auto& path : paths)
      for (std::size_t k = 0; k < path.size(); k += 10)
        ASSERT_GE(distance_to_quad(path[k].pose.t, world.quads()[i]), options.clearance_m - 1e-9) << "quad " << i;
  // The hall encloses every path with the margin.
  for (const auto& path : paths)
    for (const auto& s : path) {
      EXPECT_TRUE((s.pose.t.array() > bounds.min.array()).all());
      EXPECT_TRUE((s.pose.t.array() < bounds.max.array()).all());
    }

  const sim::World again = sim::build_machine_hall(paths, options);
  ASSERT_EQ(again.quads().size(), world.quads().size());
  for (std::size_t i = 0; i < world.quads().size(); ++i) {
    EXPECT_EQ(again.quads()[i].origin, world.quads()[i].origin);
    const cv::Mat& a = world.texture(world.quads()[i].texture).levels[0];
    const cv::Mat& b = again.texture(again.quads()[i].texture).levels[0];
    ASSERT_EQ(cv::norm(a, b, cv::NORM_L1), 0.0) << "texture " << i << " differs between two builds";
  }
  options.seed = 6;
  const sim::World other = sim::build_machine_hall(paths, options);
  EXPECT_GT(cv::norm(other.texture(0).levels[0], world.texture(0).levels[0], cv::NORM_L1), 0.0);
}

TEST(Texture, IsRichAndDoesNotRepeat) {
  sim::TextureRequest req;
  req.width_m = 2.0;
  req.height_m = 1.0;
  req.seed = 3;
  const sim::Texture tex = sim::make_texture(req);
  const cv::Mat& img = tex.levels[0];
  ASSERT_EQ(img.cols, 400);
  ASSERT_EQ(img.rows, 200);
  EXPECT_GT(tex.levels.size(), 5u);
  // Two halves of one texture are different (no tiling), and both are textured.
  const cv::Mat left = img(cv::Rect(0, 0, 200, 200)), right = img(cv::Rect(200, 0, 200, 200));
  EXPECT_GT(cv::norm(left, right, cv::NORM_L1) / (200.0 * 200.0), 10.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img, mean, stddev);
  EXPECT_GT(stddev[0], 25.0);
}

}  // namespace
}  // namespace orbatlas
