// The Sim3 type, Horn's absolute orientation and the correction helpers of
// loop closing against exact synthetic ground truth. The RANSAC Sim3Solver is
// in test_sim3_solver.cc, the OptimizeSim3 refinement in
// test_sim3_refinement.cc.
#include <gtest/gtest.h>

#include <optional>
#include <random>
#include <vector>

#include "core/common/error.h"
#include "core/estimators/absolute_orientation.h"
#include "core/geometry/sim3.h"
#include "core/geometry/sim3_correction.h"
#include "core/geometry/so3.h"
#include "tests/support/sim3_scenes.h"

namespace orbatlas {
namespace {

using test::expect_sim3_near;
using test::gaussian3;
using test::random_sim3;

TEST(Sim3, ComposesInvertsAndMapsPoints) {
  std::mt19937 rng(3);
  const Sim3 a = random_sim3(rng, 1.0, 2.0, 1.7);
  const Sim3 b = random_sim3(rng, 2.0, 0.5, 0.4);
  const Eigen::Vector3d p(0.3, -1.2, 4.0);
  EXPECT_LE(((a * b) * p - a * (b * p)).norm(), 1e-12);
  EXPECT_LE((a.inverse() * (a * p) - p).norm(), 1e-12);
  EXPECT_LE(((a * a.inverse()).matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  EXPECT_LE(((a * b).matrix() - a.matrix() * b.matrix()).norm(), 1e-12);
  EXPECT_NEAR((a * p - a.t).norm(), 1.7 * p.norm(), 1e-12);

  const Pose3 T(so3_exp(Eigen::Vector3d(0.1, 0.2, -0.3)), Eigen::Vector3d(1, 2, 3));
  const Sim3 S(T);
  EXPECT_EQ(S.s, 1.0);
  EXPECT_LE((S * p - T * p).norm(), 1e-12);
  const Pose3 back = S.to_pose3();
  EXPECT_LE(translation_distance(back, T), 1e-12);
  EXPECT_LE(rotation_distance(back, T), 1e-12);
  EXPECT_THROW(a.to_pose3(), Error);  // scale 1.7 cannot be dropped silently
  EXPECT_THROW(Sim3(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), 0.0), Error);
  EXPECT_THROW(Sim3(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), -1.0), Error);
  EXPECT_THROW(Sim3(Eigen::Quaterniond(0, 0, 0, 0), Eigen::Vector3d::Zero(), 1.0), Error);
}

TEST(Horn, RecoversSimilarityExactly) {
  std::mt19937 rng(5);
  for (const bool estimate_scale : {true, false}) {
    for (const int n : {3, 4, 50}) {
      const Sim3 S_1_2 = random_sim3(rng, 2.5, 3.0, estimate_scale ? 0.35 : 1.0);
      std::vector<Eigen::Vector3d> p1, p2;
      for (int i = 0; i < n; ++i) {
        p2.push_back(gaussian3(rng, 2.0));
        p1.push_back(S_1_2 * p2.back());
      }
      const std::optional<Sim3> est = horn_absolute_orientation(p1, p2, estimate_scale);
      ASSERT_TRUE(est.has_value());
      expect_sim3_near(*est, S_1_2, 1e-9, 1e-9, 1e-12);
      if (!estimate_scale) {
        EXPECT_EQ(est->s, 1.0);
      }
      // Horn's symmetric scale: aligning 2 onto 1 gives exactly the inverse.
      const std::optional<Sim3> inv = horn_absolute_orientation(p2, p1, estimate_scale);
      ASSERT_TRUE(inv.has_value());
      expect_sim3_near(*inv, S_1_2.inverse(), 1e-9, 1e-9, 1e-12);
    }
  }
}

TEST(Horn, NoisyPointsGiveCloseEstimate) {
  std::mt19937 rng(6);
  const Sim3 S_1_2 = random_sim3(rng, 0.7, 1.0, 2.0);
  std::vector<Eigen::Vector3d> p1, p2;
  for (int i = 0; i < 500; ++i) {
    p2.push_back(gaussian3(rng, 3.0));
    p1.push_back(S_1_2 * p2.back() + gaussian3(rng, 0.01));
  }
  const std::optional<Sim3> est = horn_absolute_orientation(p1, p2, true);
  ASSERT_TRUE(est.has_value());
  expect_sim3_near(*est, S_1_2, 1e-3, 3e-3, 1e-3);
}

TEST(Horn, RejectsDegenerateInput) {
  const std::vector<Eigen::Vector3d> line{{0, 0, 1}, {0, 0, 2}, {0, 0, 3.5}};
  const std::vector<Eigen::Vector3d> line2{{1, 0, 1}, {2, 0, 1}, {3.5, 0, 1}};
  EXPECT_FALSE(horn_absolute_orientation(line, line2, true).has_value());
  const std::vector<Eigen::Vector3d> same{{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  EXPECT_FALSE(horn_absolute_orientation(same, line, false).has_value());
  const std::vector<Eigen::Vector3d> two{{0, 0, 1}, {1, 0, 1}};
  EXPECT_THROW(horn_absolute_orientation(two, two, true), Error);
  EXPECT_THROW(horn_absolute_orientation(line, two, true), Error);
}

// The old map is the true map seen through a world similarity W (drift):
// p_w_old = W * p_w_true, and every old keyframe pose is rigid with camera
// coordinates in the drifted scale: T_c_w_old = s_W * T_c_w_true * W^-1. The
// correct S_c_w_new = T_c_w_old * W must bring points and poses back to the truth.
TEST(Sim3Correction, UndoesASimilarityDriftExactly) {
  std::mt19937 rng(101);
  const Sim3 W = random_sim3(rng, 0.4, 2.0, 1.35);
  const Sim3 scale_W(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), W.s);
  const Pose3 T_c_w_true(so3_exp(gaussian3(rng, 0.5)), gaussian3(rng, 3.0));
  const Pose3 T_i_w_true(so3_exp(gaussian3(rng, 0.5)), gaussian3(rng, 3.0));
  const Pose3 T_c_w_old = (scale_W * Sim3(T_c_w_true) * W.inverse()).to_pose3();
  const Pose3 T_i_w_old = (scale_W * Sim3(T_i_w_true) * W.inverse()).to_pose3();
  const Sim3 S_c_w_new = Sim3(T_c_w_old) * W;

  // Neighbour i follows c rigidly.
  const Sim3 S_i_w_new = propagate_correction(T_i_w_old, T_c_w_old, S_c_w_new);
  const Pose3 T_c_w_new = rigid_pose_c_w(S_c_w_new);
  const Pose3 T_i_w_new = rigid_pose_c_w(S_i_w_new);
  EXPECT_LE(translation_distance(T_c_w_new, T_c_w_true), 1e-12);
  EXPECT_LE(rotation_distance(T_c_w_new, T_c_w_true), 1e-12);
  EXPECT_LE(translation_distance(T_i_w_new, T_i_w_true), 1e-12);
  EXPECT_LE(rotation_distance(T_i_w_new, T_i_w_true), 1e-12);
  EXPECT_NEAR(S_i_w_new.s, W.s, 1e-12);

  for (int k = 0; k < 20; ++k) {
    const Eigen::Vector3d p_true = gaussian3(rng, 4.0);
    const Eigen::Vector3d p_old = W * p_true;
    EXPECT_LE((correct_point(T_c_w_old, S_c_w_new, p_old) - p_true).norm(), 1e-12);
    EXPECT_LE((correct_point(T_i_w_old, S_i_w_new, p_old) - p_true).norm(), 1e-12);
    // The keyframe's view is unchanged up to the scale: same pixel, 1/s the depth.
    EXPECT_LE((T_c_w_new * p_true - (T_c_w_old * p_old) / S_c_w_new.s).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace orbatlas
