// Visual-inertial SLAM (issue 19), first stage, through the runner: a
// stereo-inertial config fuses the clip's imu0. Keyframes are linked by the IMU
// preintegrated between them, and after about 2 s of keyframes the map gets its
// inertial initialisation: it is turned so that gravity is -z of its frame, and
// gets the IMU biases, compared with the simulator's truth (the direction of
// gravity in the first frame's body; the synthetic IMU has noise and drifting
// biases).
#include <gtest/gtest.h>

#include "core/common/data_paths.h"
#include "core/slam/dataset_runner.h"
#include "tests/slam_test_clip.h"

namespace orbatlas {
namespace {

TEST(InertialSlam, AStereoInertialRunInitialisesItsMapsGravityAndBiases) {
  const auto clip = test::simulated_clip("MH_01", 40.0, 8.0);
  test::ClipCleanup cleanup{clip};
  DatasetRunOptions options;
  options.settings = shipped_config_dir() / "euroc" / "stereo_inertial.yaml";
  options.dataset = clip;
  options.show_progress = false;
  options.slam.synchronous_mapping = true;  // the initialisation sees every keyframe as it comes
  const DatasetRunReport report = run_stereo_dataset(options);
  const SlamStats& s = report.stats;
  ASSERT_TRUE(s.inertial);
  EXPECT_EQ(s.tracked, s.frames);
  EXPECT_GT(s.imu_samples, 1500u);  // 200 Hz over 8 s
  EXPECT_EQ(s.imu_uncovered_keyframes, 0u);
  EXPECT_EQ(s.imu_linked_keyframes + 1, s.keyframes_made);  // every keyframe but the map's first
  ASSERT_TRUE(s.imu_initialized_at_s.has_value()) << "no inertial initialisation after 8 s";
  EXPECT_GE(*s.imu_initialized_at_s, 2.0);

  const EurocDataset data = test::stereo_dataset(clip);
  const auto frames = pair_stereo_frames(data);
  Trajectory gt;
  for (const auto& g : data.ground_truth) gt.push_back({g.t_ns, g.T_w_b});
  const auto first = pose_at(gt, frames.front().t_ns, 50'000'000);
  ASSERT_TRUE(first.has_value());
  // The map was turned so that gravity is -z of its frame: the first frame's
  // body sees gravity where it truly was (yaw is free: only the direction in
  // the body is compared).
  EXPECT_LT((s.imu_gravity_w - Eigen::Vector3d(0.0, 0.0, -9.81)).norm(), 1e-9);
  ASSERT_FALSE(report.trajectory.empty());
  ASSERT_EQ(report.trajectory.front().t_ns, frames.front().t_ns);
  const Eigen::Vector3d gravity_in_body = report.trajectory.front().pose.q.conjugate() * s.imu_gravity_w;
  const Eigen::Vector3d gravity_true = first->q.conjugate() * Eigen::Vector3d(0.0, 0.0, -9.81);
  const double gravity_deg =
      std::atan2(gravity_in_body.cross(gravity_true).norm(), gravity_in_body.dot(gravity_true)) * 180.0 / M_PI;
  // The true biases at the initialisation.
  const TimestampNs at = frames.front().t_ns + s_to_ns(*s.imu_initialized_at_s);
  const auto truth = std::min_element(data.ground_truth.begin(), data.ground_truth.end(),
                                      [at](const GroundTruthState& a, const GroundTruthState& b) {
                                        return std::llabs(a.t_ns - at) < std::llabs(b.t_ns - at);
                                      });
  const double gyro_error = (s.imu_bias.gyro - truth->gyro_bias).norm();
  std::printf(
      "initialised at %.2f s with %zu linked keyframes: gravity off by %.3f deg, gyro bias off by %.5f rad/s "
      "(true %.4f), accelerometer bias %.3f (true %.3f) m/s^2\n",
      *s.imu_initialized_at_s, s.imu_linked_keyframes, gravity_deg, gyro_error, truth->gyro_bias.norm(),
      s.imu_bias.accel.norm(), truth->accel_bias.norm());
  EXPECT_LT(gravity_deg, 0.7);    // measured 0.32 deg
  EXPECT_LT(gyro_error, 0.0005);  // measured 0.0002 rad/s (true bias 0.016)
  const nlohmann::json j = report.to_json();
  EXPECT_TRUE(j.contains("imu_initialized_at_s"));
  EXPECT_EQ(j["imu_bias"]["gyro"].size(), 3u);
}

}  // namespace
}  // namespace orbatlas
