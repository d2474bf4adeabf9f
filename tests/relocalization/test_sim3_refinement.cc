// The OptimizeSim3 refinement of loop closing against exact synthetic ground
// truth: its chained Jacobians against Ceres's automatic ones, convergence
// with and without scale, outliers dropped, noise, and bad input.
#include <ceres/autodiff_cost_function.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "core/camera/camera_factory.h"
#include "core/camera/kannala_brandt.h"
#include "core/camera/pinhole_radtan.h"
#include "core/common/error.h"
#include "core/geometry/sim3.h"
#include "core/optimization/sim3_costs.h"
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
using test::perturb;
using test::random_sim3;
using test::SceneOptions;
using test::Sim3Scene;

template <class CameraT>
struct AutodiffSim3Cost {
  const CameraT* camera;
  Eigen::Vector3d p;
  Eigen::Vector2d uv;
  double inv_sigma;
  bool inverse;

  template <typename T>
  bool operator()(const T* q_, const T* t_, const T* ls, T* r) const {
    using std::exp;
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(t_);
    const Eigen::Matrix<T, 3, 1> pt = p.cast<T>();
    const Eigen::Matrix<T, 3, 1> p_c = inverse ? Eigen::Matrix<T, 3, 1>((q.conjugate() * (pt - t)) / exp(ls[0]))
                                               : Eigen::Matrix<T, 3, 1>(exp(ls[0]) * (q * pt) + t);
    T proj[2];
    if (!camera->project_t(p_c.data(), proj)) return false;
    r[0] = (T(uv.x()) - proj[0]) * inv_sigma;
    r[1] = (T(uv.y()) - proj[1]) * inv_sigma;
    return true;
  }
};

template <class CameraT>
void expect_chained_matches_autodiff(const CameraT& camera) {
  std::mt19937 rng(51);
  const Sim3 S = random_sim3(rng, 0.3, 0.5, 1.4);
  const double q[4] = {S.q.x(), S.q.y(), S.q.z(), S.q.w()};
  const double t[3] = {S.t.x(), S.t.y(), S.t.z()};
  const double ls[1] = {std::log(S.s)};
  const double* params[3] = {q, t, ls};
  for (const bool inverse : {false, true}) {
    // A point in front of the camera after the transform.
    const Eigen::Vector3d p_c(0.4, -0.3, 3.0);
    const Eigen::Vector3d p = inverse ? Eigen::Vector3d(S * p_c) : Eigen::Vector3d(S.inverse() * p_c);
    const Eigen::Vector2d uv(300.0, 200.0);
    const auto chained =
        make_sim3_projection_cost(camera, p, uv, 1.44, inverse ? Sim3Projection::kInverse : Sim3Projection::kForward);
    ceres::AutoDiffCostFunction<AutodiffSim3Cost<CameraT>, 2, 4, 3, 1> autodiff(
        new AutodiffSim3Cost<CameraT>{&camera, p, uv, 1.0 / 1.2, inverse});
    double r1[2], r2[2], jq1[8], jq2[8], jt1[6], jt2[6], js1[2], js2[2];
    double* j1[3] = {jq1, jt1, js1};
    double* j2[3] = {jq2, jt2, js2};
    ASSERT_TRUE(chained->Evaluate(params, r1, j1));
    ASSERT_TRUE(autodiff.Evaluate(params, r2, j2));
    for (int k = 0; k < 2; ++k) EXPECT_NEAR(r1[k], r2[k], 1e-9);
    for (int k = 0; k < 8; ++k) EXPECT_NEAR(jq1[k], jq2[k], 1e-7 * (1.0 + std::abs(jq2[k]))) << k;
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(jt1[k], jt2[k], 1e-7 * (1.0 + std::abs(jt2[k]))) << k;
    for (int k = 0; k < 2; ++k) EXPECT_NEAR(js1[k], js2[k], 1e-7 * (1.0 + std::abs(js2[k]))) << k;
  }
}

TEST(Sim3Refinement, ChainedCostsMatchAutodiff) {
  const PinholeRadTan pinhole(test::euroc_cam0());
  expect_chained_matches_autodiff(pinhole);
  const KannalaBrandt fisheye(test::fisheye_left());
  expect_chained_matches_autodiff(fisheye);
}

void expect_refinement_exact(const Camera& cam1, const Camera& cam2, bool fix_scale, double outliers) {
  std::mt19937 rng(61);
  SceneOptions so;
  so.scale = fix_scale ? 1.0 : 0.7;
  so.outlier_fraction = outliers;
  const Sim3Scene scene = make_scene(cam1, cam2, so, rng);
  const Sim3 start = perturb(scene.S_1_2, 1.0 * kDegree, 0.03, fix_scale ? 1.0 : 1.03, rng);
  Sim3RefinementOptions options;
  options.fix_scale = fix_scale;
  const Sim3RefinementResult r = refine_sim3(start, scene.matches, cam1, cam2, options);
  ASSERT_TRUE(r.success);
  expect_sim3_near(r.S_1_2, scene.S_1_2, 1e-6, 1e-6, 1e-6);
  if (fix_scale) {
    EXPECT_EQ(r.S_1_2.s, 1.0);
  }
  for (std::size_t i = 0; i < scene.matches.size(); ++i) EXPECT_EQ(r.inliers[i], scene.is_outlier[i] ? 0 : 1) << i;
  EXPECT_EQ(r.inlier_count, count(r.inliers));
  EXPECT_GT(r.iterations, 0);
}

TEST(Sim3Refinement, ConvergesExactlySim3) {
  const auto cam = make_camera(test::euroc_cam0());
  expect_refinement_exact(*cam, *cam, false, 0.0);
}

TEST(Sim3Refinement, ConvergesExactlySe3) {
  const auto cam = make_camera(test::euroc_cam0());
  expect_refinement_exact(*cam, *cam, true, 0.0);
}

TEST(Sim3Refinement, DropsOutliersAndConvergesExactly) {
  const auto pinhole = make_camera(test::euroc_cam0());
  const auto fisheye = make_camera(test::fisheye_left());
  expect_refinement_exact(*pinhole, *pinhole, false, 0.25);
  expect_refinement_exact(*fisheye, *pinhole, false, 0.25);
  expect_refinement_exact(*pinhole, *fisheye, true, 0.25);
}

TEST(Sim3Refinement, NoisyWithOutliersAndTiming) {
  const auto cam = make_camera(test::euroc_cam0());
  std::mt19937 rng(71);
  SceneOptions so;
  so.matches = 200;
  so.scale = 1.8;
  so.outlier_fraction = 0.2;
  so.pixel_noise = 1.0;
  so.depth_noise = 0.01;
  const Sim3Scene scene = make_scene(*cam, *cam, so, rng);
  const Sim3 start = perturb(scene.S_1_2, 1.0 * kDegree, 0.03, 1.02, rng);
  const Sim3RefinementResult r = refine_sim3(start, scene.matches, *cam, *cam);
  ASSERT_TRUE(r.success);
  const auto [recall, kept] = classification(r.inliers, scene.is_outlier);
  // Over 40 seeds: recall 100%, kept >= 96%, worst 0.07 deg, 6 mm, 1.6% scale. The
  // scale is the weak part: with a 0.4 m baseline a 1% scale change moves a point
  // at 5 m by ~0.4 px in the other image.
  EXPECT_GE(recall, 99.0);
  EXPECT_GE(kept, 90.0);
  expect_sim3_near(r.S_1_2, scene.S_1_2, 0.15 * kDegree, 0.012, 0.04);
}

TEST(Sim3Refinement, FailsWithTooFewMatchesAndRejectsBadInput) {
  const auto cam = make_camera(test::euroc_cam0());
  std::mt19937 rng(81);
  SceneOptions so;
  so.matches = 8;  // below min_inliers = 10
  const Sim3Scene scene = make_scene(*cam, *cam, so, rng);
  const Sim3RefinementResult r = refine_sim3(scene.S_1_2, scene.matches, *cam, *cam);
  EXPECT_FALSE(r.success);
  EXPECT_EQ(r.inlier_count, 0);
  EXPECT_EQ(r.S_1_2.matrix(), scene.S_1_2.matrix());

  std::vector<Sim3Match> wrong = scene.matches;
  wrong[0].level_sigma2_1 = -1.0;
  EXPECT_THROW(refine_sim3(scene.S_1_2, wrong, *cam, *cam), Error);
  Sim3RefinementOptions bad;
  bad.chi2_threshold = 0.0;
  EXPECT_THROW(refine_sim3(scene.S_1_2, scene.matches, *cam, *cam, bad), Error);
}

}  // namespace
}  // namespace orbatlas
