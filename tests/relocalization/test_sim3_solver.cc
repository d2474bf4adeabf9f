// The RANSAC Sim3Solver of loop closing against exact synthetic ground truth
// (pinhole and fisheye cameras, outliers, noise), and RANSAC followed by the
// OptimizeSim3 refinement.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/common/error.h"
#include "core/estimators/sim3_solver.h"
#include "core/geometry/sim3.h"
#include "core/optimization/sim3_refinement.h"
#include "tests/support/sim3_scenes.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

using test::classification;
using test::count;
using test::expect_sim3_near;
using test::kDegree;
using test::make_scene;
using test::SceneOptions;
using test::Sim3Scene;

void expect_ransac_exact(const Camera& cam1, const Camera& cam2, bool fix_scale) {
  std::mt19937 rng(11);
  SceneOptions so;
  so.scale = fix_scale ? 1.0 : 0.6;
  so.outlier_fraction = 0.4;
  const Sim3Scene scene = make_scene(cam1, cam2, so, rng);
  Sim3SolverOptions options;
  options.fix_scale = fix_scale;
  const Sim3SolverResult r = solve_sim3_ransac(scene.matches, cam1, cam2, options);
  ASSERT_TRUE(r.success);
  expect_sim3_near(r.S_1_2, scene.S_1_2, 1e-6, 1e-6, 1e-6);
  if (fix_scale) {
    EXPECT_EQ(r.S_1_2.s, 1.0);
  }
  for (std::size_t i = 0; i < scene.matches.size(); ++i) EXPECT_EQ(r.inliers[i], scene.is_outlier[i] ? 0 : 1) << i;
  EXPECT_EQ(r.inlier_count, count(r.inliers));
  EXPECT_GE(r.iterations, 1);
  EXPECT_LE(r.iterations, options.max_iterations);
}

TEST(Sim3Solver, ExactSim3WithOutliersPinhole) {
  const auto cam = make_camera(test::euroc_cam0());
  expect_ransac_exact(*cam, *cam, false);
}

TEST(Sim3Solver, ExactSe3WithOutliersPinhole) {
  const auto cam = make_camera(test::euroc_cam0());
  expect_ransac_exact(*cam, *cam, true);
}

TEST(Sim3Solver, ExactSim3WithOutliersPinholeAndFisheye) {
  const auto pinhole = make_camera(test::euroc_cam0());
  const auto fisheye = make_camera(test::fisheye_left());
  expect_ransac_exact(*pinhole, *fisheye, false);
}

TEST(Sim3Solver, NoisyHalfOutliersAndTiming) {
  const auto cam = make_camera(test::euroc_cam0());
  for (const bool fix_scale : {false, true}) {
    std::mt19937 rng(21);
    SceneOptions so;
    so.matches = 200;
    so.scale = fix_scale ? 1.0 : 1.8;
    so.outlier_fraction = 0.5;
    so.pixel_noise = 1.0;
    so.depth_noise = 0.01;
    const Sim3Scene scene = make_scene(*cam, *cam, so, rng);
    Sim3SolverOptions options;
    options.fix_scale = fix_scale;
    const Sim3SolverResult r = solve_sim3_ransac(scene.matches, *cam, *cam, options);
    ASSERT_TRUE(r.success);
    const auto [recall, kept] = classification(r.inliers, scene.is_outlier);
    // Over 40 seeds: recall 100%, kept >= 80%, worst 0.29 deg, 37 mm, 1.6% scale.
    EXPECT_GE(recall, 99.0);
    EXPECT_GE(kept, 70.0);
    expect_sim3_near(r.S_1_2, scene.S_1_2, 0.5 * kDegree, 0.06, 0.04);
  }
}

TEST(Sim3Solver, TooFewMatchesOrInliersFail) {
  const auto cam = make_camera(test::euroc_cam0());
  std::mt19937 rng(31);
  SceneOptions so;
  so.matches = 2;
  const Sim3Scene two = make_scene(*cam, *cam, so, rng);
  Sim3SolverResult r = solve_sim3_ransac(two.matches, *cam, *cam);
  EXPECT_FALSE(r.success);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.inliers.size(), 2u);

  so.matches = 15;  // below min_inliers = 20: no search at all
  const Sim3Scene few = make_scene(*cam, *cam, so, rng);
  r = solve_sim3_ransac(few.matches, *cam, *cam);
  EXPECT_FALSE(r.success);
  EXPECT_EQ(r.iterations, 0);

  // All outliers: the search runs its budget and fails.
  so.matches = 60;
  so.outlier_fraction = 1.0;
  const Sim3Scene bad = make_scene(*cam, *cam, so, rng);
  r = solve_sim3_ransac(bad.matches, *cam, *cam);
  EXPECT_FALSE(r.success);
  EXPECT_LT(r.inlier_count, 20);

  std::vector<Sim3Match> wrong = few.matches;
  wrong[3].level_sigma2_2 = 0.0;
  EXPECT_THROW(static_cast<void>(Sim3Solver(wrong, *cam, *cam)), Error);
}

TEST(Sim3Solver, SeededAndIncrementalRunsAgree) {
  const auto cam = make_camera(test::euroc_cam0());
  std::mt19937 rng(41);
  SceneOptions so;
  so.outlier_fraction = 0.6;
  so.pixel_noise = 1.0;
  const Sim3Scene scene = make_scene(*cam, *cam, so, rng);
  const Sim3SolverResult a = solve_sim3_ransac(scene.matches, *cam, *cam);
  const Sim3SolverResult b = solve_sim3_ransac(scene.matches, *cam, *cam);
  Sim3Solver incremental(scene.matches, *cam, *cam);
  int calls = 0;
  while (!incremental.iterate(5)) ++calls;
  const Sim3SolverResult c = incremental.result();
  ASSERT_TRUE(a.success);
  EXPECT_GT(calls, 0);
  for (const Sim3SolverResult* other : {&b, &c}) {
    EXPECT_EQ(other->iterations, a.iterations);
    EXPECT_EQ(other->inliers, a.inliers);
    EXPECT_EQ(other->S_1_2.matrix(), a.S_1_2.matrix());
  }
}

TEST(Sim3Pipeline, RansacThenRefinement) {
  const auto cam = make_camera(test::euroc_cam0());
  std::mt19937 rng(91);
  SceneOptions so;
  so.scale = 0.5;
  so.outlier_fraction = 0.5;
  so.pixel_noise = 1.0;
  so.depth_noise = 0.01;
  const Sim3Scene scene = make_scene(*cam, *cam, so, rng);
  const Sim3SolverResult ransac = solve_sim3_ransac(scene.matches, *cam, *cam);
  ASSERT_TRUE(ransac.success);
  const Sim3RefinementResult refined = refine_sim3(ransac.S_1_2, scene.matches, *cam, *cam);
  ASSERT_TRUE(refined.success);
  // Over 40 seeds: worst 0.12 deg, 9 mm, 4.7% scale (see NoisyWithOutliersAndTiming:
  // reprojection constrains the scale weakly at small baselines; the 3D fit of the
  // RANSAC is sometimes closer in scale).
  expect_sim3_near(refined.S_1_2, scene.S_1_2, 0.25 * kDegree, 0.02, 0.08);
  const auto [recall, kept] = classification(refined.inliers, scene.is_outlier);
  EXPECT_GE(recall, 99.0);
  EXPECT_GE(kept, 90.0);
}

}  // namespace
}  // namespace orbatlas
