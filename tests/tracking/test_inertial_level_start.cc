// A visual-inertial map starts level: the first frame's rotation points the
// gravity its IMU measured along the world's -z. Against the exact tilt of a
// rig at rest, with the IMU mounted turned in the body.
#include <gtest/gtest.h>

#include <cmath>

#include "core/tracking/inertial_tracking.h"

namespace orbatlas {
namespace {

constexpr TimestampNs kStart = 1'000'000'000;
constexpr TimestampNs kStep = 5'000'000;  // 200 Hz

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / M_PI;
}

// A rig at rest with body rotation R_w_b: its IMU (at T_b_i) reads the
// specific force R_i_w (0, 0, g) plus `offset` on every sample, for 1 s.
void fill_at_rest(ImuBuffer& buffer, const Eigen::Quaterniond& R_w_b, const Pose3& T_b_i, double g,
                  const Eigen::Vector3d& offset = Eigen::Vector3d::Zero()) {
  const Eigen::Quaterniond R_w_i = R_w_b * T_b_i.q;
  std::vector<ImuSample> samples;
  for (int k = 0; k < 200; ++k) {
    ImuSample s;
    s.t_ns = kStart + k * kStep;
    s.accel = R_w_i.conjugate() * Eigen::Vector3d(0.0, 0.0, g) + offset;
    samples.push_back(s);
  }
  buffer.add(samples);
}

Pose3 turned_imu() {
  Pose3 T_b_i;
  T_b_i.q = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitY()));
  T_b_i.t = Eigen::Vector3d(0.02, -0.06, 0.01);
  return T_b_i;
}

TEST(InertialLevelStart, TheFirstFramesRotationPutsTheMeasuredGravityAlongMinusZ) {
  const Eigen::Quaterniond R_w_b_true = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()) *
                                        Eigen::AngleAxisd(-0.35, Eigen::Vector3d::UnitY()) *
                                        Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitX());
  const Pose3 T_b_i = turned_imu();
  ImuBuffer buffer;
  fill_at_rest(buffer, R_w_b_true, T_b_i, 9.81);
  const InertialTracking inertial(buffer, ImuNoise{}, T_b_i, Pose3{});
  const auto level = inertial.level_rotation(kStart + 199 * kStep);
  ASSERT_TRUE(level.has_value());
  // Gravity in the body, as the level start puts it in the world: -z exactly.
  const Eigen::Vector3d down_b = R_w_b_true.conjugate() * Eigen::Vector3d(0.0, 0.0, -1.0);
  EXPECT_LT(angle_deg(*level * down_b, Eigen::Vector3d(0.0, 0.0, -1.0)), 1e-9);
  // The least turn: the level start differs from the truth by a yaw only.
  const Eigen::Quaterniond diff = *level * R_w_b_true.conjugate();
  EXPECT_LT(angle_deg(diff * Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()), 1e-9);
}

TEST(InertialLevelStart, AnAccelerometerOffByABiasTiltsTheStartByWhatItAdds) {
  // 0.1 m/s^2 across gravity: the start is off by atan(0.1 / 9.81) = 0.584 deg.
  const Eigen::Quaterniond R_w_b_true(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  ImuBuffer buffer;
  fill_at_rest(buffer, R_w_b_true, Pose3{}, 9.81, R_w_b_true.conjugate() * Eigen::Vector3d(0.1, 0.0, 0.0));
  const InertialTracking inertial(buffer, ImuNoise{}, Pose3{}, Pose3{});
  const auto level = inertial.level_rotation(kStart + 199 * kStep);
  ASSERT_TRUE(level.has_value());
  const Eigen::Vector3d down_b = R_w_b_true.conjugate() * Eigen::Vector3d(0.0, 0.0, -1.0);
  EXPECT_NEAR(angle_deg(*level * down_b, Eigen::Vector3d(0.0, 0.0, -1.0)), std::atan(0.1 / 9.81) * 180.0 / M_PI, 1e-9);
}

TEST(InertialLevelStart, NoLevelWithoutSamplesOrFromAMeanFarFromGravity) {
  const Eigen::Quaterniond R_w_b(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()));
  {
    ImuBuffer buffer;
    const InertialTracking inertial(buffer, ImuNoise{}, Pose3{}, Pose3{});
    EXPECT_FALSE(inertial.level_rotation(kStart).has_value());  // no sample yet
  }
  for (const double g : {4.8, 19.8}) {  // falling, or thrown about: the mean is not gravity
    ImuBuffer buffer;
    fill_at_rest(buffer, R_w_b, Pose3{}, g);
    const InertialTracking inertial(buffer, ImuNoise{}, Pose3{}, Pose3{});
    EXPECT_FALSE(inertial.level_rotation(kStart + 199 * kStep).has_value()) << g;
  }
  ImuBuffer buffer;
  fill_at_rest(buffer, R_w_b, Pose3{}, 5.0);  // half to twice 9.81: a push along gravity does not tilt it
  const InertialTracking inertial(buffer, ImuNoise{}, Pose3{}, Pose3{});
  EXPECT_TRUE(inertial.level_rotation(kStart + 199 * kStep).has_value());
  // One sample is enough (a stream that starts with the first image).
  ImuBuffer one;
  one.add({ImuSample{kStart, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, 9.81)}});
  EXPECT_TRUE(InertialTracking(one, ImuNoise{}, Pose3{}, Pose3{}).level_rotation(kStart).has_value());
}

}  // namespace
}  // namespace orbatlas
