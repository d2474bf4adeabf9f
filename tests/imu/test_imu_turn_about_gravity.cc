// How far a rig turned about gravity (core/imu/turn_about_gravity.h): exact
// headings of rotations built from known turns, whichever way the rig is held
// and whichever way the world's gravity points.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "core/imu/turn_about_gravity.h"

namespace orbatlas {
namespace {

Eigen::Matrix3d about(const Eigen::Vector3d& axis, double deg) {
  return Eigen::AngleAxisd(deg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
}

// A rig held as `mount` (the IMU in a level frame) turning about the up of a
// world whose gravity is `gravity_w`, through the headings `degs`.
std::vector<Eigen::Matrix3d> turning(const Eigen::Matrix3d& mount, const Eigen::Vector3d& gravity_w,
                                     const std::vector<double>& degs) {
  // The world's frame whose -z is gravity, in the world.
  const Eigen::Matrix3d R_w_level =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(0.0, 0.0, -1.0), gravity_w).toRotationMatrix();
  std::vector<Eigen::Matrix3d> R;
  for (double d : degs) R.push_back(R_w_level * about(Eigen::Vector3d::UnitZ(), d) * mount);
  return R;
}

TEST(TurnAboutGravity, IsTheSpreadOfTheRigsHeadings) {
  const Eigen::Vector3d down(0.0, 0.0, -9.81);
  // A drone (IMU level, x forward) turning back and forth: 20 to -40 degrees.
  EXPECT_NEAR(turn_about_gravity_deg(turning(Eigen::Matrix3d::Identity(), down, {0.0, 20.0, 5.0, -40.0, -10.0}), down),
              60.0, 1e-9);
  // Held on its side (the IMU's y up) and pitched by 10 degrees: the same turn.
  const Eigen::Matrix3d side = about(Eigen::Vector3d::UnitX(), 90.0) * about(Eigen::Vector3d::UnitZ(), 10.0);
  EXPECT_NEAR(turn_about_gravity_deg(turning(side, down, {0.0, 20.0, 5.0, -40.0, -10.0}), down), 60.0, 1e-9);
  // Gravity along another axis of the world (a map not yet levelled).
  const Eigen::Vector3d tilted = about(Eigen::Vector3d(1.0, 2.0, 0.0), 70.0) * down;
  EXPECT_NEAR(turn_about_gravity_deg(turning(side, tilted, {0.0, 20.0, 5.0, -40.0, -10.0}), tilted), 60.0, 1e-9);
}

TEST(TurnAboutGravity, ATiltOrNoTurnIsNoTurn) {
  const Eigen::Vector3d down(0.0, 0.0, -9.81);
  // Rolling and pitching in place leave the heading where it is.
  std::vector<Eigen::Matrix3d> rocking;
  for (double d : {0.0, 10.0, -15.0, 5.0})
    rocking.push_back(about(Eigen::Vector3d::UnitX(), d) * about(Eigen::Vector3d::UnitY(), -d / 2.0));
  EXPECT_LT(turn_about_gravity_deg(rocking, down), 4.0);  // second order in the tilts: measured 1.95
  EXPECT_EQ(turn_about_gravity_deg(turning(Eigen::Matrix3d::Identity(), down, {30.0, 30.0}), down), 0.0);
  EXPECT_EQ(turn_about_gravity_deg({Eigen::Matrix3d::Identity()}, down), 0.0);
  EXPECT_EQ(turn_about_gravity_deg({}, down), 0.0);
  EXPECT_EQ(turn_about_gravity_deg(turning(Eigen::Matrix3d::Identity(), down, {0.0, 90.0}), Eigen::Vector3d::Zero()),
            0.0);
}

}  // namespace
}  // namespace orbatlas
