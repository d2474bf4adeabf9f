#include <gtest/gtest.h>

#include <random>

#include "core/common/error.h"
#include "core/geometry/pose.h"
#include "core/geometry/so3.h"
#include "core/geometry/trajectory.h"
#include "core/geometry/yaw_only.h"

namespace orbatlas {
namespace {

Pose3 random_pose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose3(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized(),
               Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

TEST(So3, ExpLogRoundTripIncludingSmallAndLargeAngles) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.0, 1.0);
  for (const double angle : {0.0, 1e-12, 1e-6, 0.3, 2.0, M_PI - 1e-6}) {
    const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    const Eigen::Vector3d w = axis * angle;
    EXPECT_LT((so3_log(so3_exp(w)) - w).norm(), 1e-9) << angle;
    const Eigen::Quaterniond expected(Eigen::AngleAxisd(angle, axis));
    EXPECT_LT(rotation_angle(expected.conjugate() * so3_exp(w)), 1e-9);
  }
}

TEST(Pose3, ComposeInverseAndMatrixAgree) {
  std::mt19937 rng(2);
  for (int i = 0; i < 50; ++i) {
    const Pose3 a = random_pose(rng), b = random_pose(rng);
    const Eigen::Vector3d p(0.3, -1.0, 2.0);
    EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
    EXPECT_LT((a.inverse() * (a * p) - p).norm(), 1e-12);
    EXPECT_LT(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
    const Pose3 back = Pose3::from_matrix(a.matrix());
    EXPECT_LT(translation_distance(a, back) + rotation_distance(a, back), 1e-12);
  }
}

TEST(Pose3, InterpolationIsGeodesic) {
  const Pose3 a(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0));
  const Pose3 b(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ())), Eigen::Vector3d(2, 0, 0));
  const Pose3 m = interpolate(a, b, 0.25);
  EXPECT_NEAR(m.t.x(), 0.5, 1e-12);
  EXPECT_NEAR(rotation_angle(m.q), 0.25, 1e-12);
}

// Two gravity-aligned worlds: a transform that is a turn about z and a move
// stays exactly itself; one with roll and pitch keeps its yaw, drops the rest
// and still takes the anchor point where it took it.
TEST(YawOnly, KeepsTheTurnAboutZAndTheAnchorPoint) {
  const Eigen::Vector3d p(1.5, -2.0, 0.7);
  const Pose3 yaw_and_move(so3_exp(Eigen::Vector3d(0.0, 0.0, 0.8)), Eigen::Vector3d(0.3, 0.1, -0.2));
  const Pose3 same = yaw_only_transform(yaw_and_move, p);
  EXPECT_LT((same.matrix() - yaw_and_move.matrix()).norm(), 1e-12);

  const Pose3 tilted(so3_exp(Eigen::Vector3d(0.0, 0.0, 0.8)) * so3_exp(Eigen::Vector3d(0.02, -0.03, 0.0)),
                     Eigen::Vector3d(0.3, 0.1, -0.2));
  const Pose3 projected = yaw_only_transform(tilted, p);
  EXPECT_LT((projected * p - tilted * p).norm(), 1e-12);
  EXPECT_LT((projected.q * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);  // no roll, pitch
  const Eigen::Vector3d x = projected.q * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(std::atan2(x.y(), x.x()), 0.8, 1e-3);  // the yaw (to first order in the tilt)
}

// Two worlds whose ups are tilted (an inertial map's refinements tilt its
// gravity instead of turning the map): a transform that takes one up to the
// other and turns about it stays exactly itself; one with more tilt keeps its
// turn about the new up, takes the old up to the new one exactly and the
// anchor point where it took it; with both ups along z it is the plain one.
TEST(YawOnly, BetweenTiltedWorldsKeepsTheTurnAboutTheirUps) {
  const Eigen::Vector3d p(1.5, -2.0, 0.7);
  const Eigen::Vector3d up_old = (so3_exp(Eigen::Vector3d(0.01, -0.004, 0.0)) * Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d up_new = (so3_exp(Eigen::Vector3d(-0.006, 0.008, 0.0)) * Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Quaterniond level = Eigen::Quaterniond::FromTwoVectors(up_old, up_new);
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(0.8, up_new));
  const Pose3 exact(turn * level, Eigen::Vector3d(0.3, 0.1, -0.2));
  const Pose3 same = yaw_only_transform(exact, p, up_new, up_old);
  EXPECT_LT((same.matrix() - exact.matrix()).norm(), 1e-12);

  const Pose3 tilted(exact.q * so3_exp(Eigen::Vector3d(0.02, -0.03, 0.0)), exact.t);
  const Pose3 projected = yaw_only_transform(tilted, p, up_new, up_old);
  EXPECT_LT((projected * p - tilted * p).norm(), 1e-12);
  EXPECT_LT((projected.q * up_old - up_new).norm(), 1e-12);  // gravity to gravity
  // Its turn about up_new, against the exact one: to first order in the tilt.
  const Eigen::Quaterniond residual = projected.q * exact.q.conjugate();
  EXPECT_LT(std::abs(Eigen::AngleAxisd(residual).angle()), 2e-3);

  const Pose3 plain(so3_exp(Eigen::Vector3d(0.0, 0.0, 0.8)) * so3_exp(Eigen::Vector3d(0.02, -0.03, 0.0)),
                    Eigen::Vector3d(0.3, 0.1, -0.2));
  const Pose3 a = yaw_only_transform(plain, p);
  const Pose3 b = yaw_only_transform(plain, p, Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ());
  EXPECT_LT((a.matrix() - b.matrix()).norm(), 1e-12);
}

TEST(Trajectory, PoseAtUsesExactSamplesInterpolatesAndRespectsGaps) {
  Trajectory tr = {{1000, Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0))},
                   {2000, Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0))},
                   {10000, Pose3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(9, 0, 0))}};
  EXPECT_NEAR(pose_at(tr, 1500, 5000, 10)->t.x(), 0.5, 1e-12);
  EXPECT_NEAR(pose_at(tr, 2003, 5000, 10)->t.x(), 1.0, 1e-12) << "within exact tolerance";
  EXPECT_FALSE(pose_at(tr, 5000, 5000, 10).has_value()) << "8000 ns gap is larger than 5000";
  EXPECT_FALSE(pose_at(tr, 500, 5000, 10).has_value()) << "before the start";
  EXPECT_FALSE(pose_at(tr, 20000, 5000, 10).has_value()) << "after the end";
  check_strictly_increasing(tr, "test");
  tr.push_back(tr.back());
  EXPECT_THROW(check_strictly_increasing(tr, "test"), DataError);
}

}  // namespace
TEST(Trajectory, JoinOrdersSessionsByTimeAndRefusesOverlap) {
  const auto at = [](TimestampNs t, double x) {
    return StampedPose{t, Pose3(Eigen::Quaterniond::Identity(), {x, 0, 0})};
  };
  const Trajectory later = {at(50, 5), at(60, 6)}, earlier = {at(10, 1), at(20, 2)};
  const Trajectory joined = join_trajectories({later, earlier}, "sessions");
  ASSERT_EQ(joined.size(), 4u);
  EXPECT_EQ(joined.front().t_ns, 10);
  EXPECT_EQ(joined.back().t_ns, 60);
  EXPECT_DOUBLE_EQ(joined[2].pose.t.x(), 5.0);
  EXPECT_THROW(join_trajectories({earlier, {at(20, 9)}}, "sessions"), DataError);
}

}  // namespace orbatlas
