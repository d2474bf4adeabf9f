// Local bundle adjustment on a synthetic map: 8 stereo keyframes along a line
// looking at ~400 points, observations from the exact projections with EuRoC cam0.
#include <gtest/gtest.h>

#include <atomic>
#include <map>
#include <random>
#include <set>

#include "core/camera/camera_factory.h"
#include "core/geometry/so3.h"
#include "core/map/atlas.h"
#include "core/optimization/local_bundle_adjustment.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

constexpr double kDegree = M_PI / 180.0;
constexpr int kKeyframes = 8;

struct World {
  Atlas atlas;
  std::shared_ptr<Map> map;
  std::unique_ptr<Camera> camera;
  double bf = 0.0;
  std::vector<std::shared_ptr<KeyFrame>> keyframes;
  std::vector<Pose3> true_T_w_b;
  std::map<MapPointId, Eigen::Vector3d> true_p_w;
  std::vector<std::pair<std::size_t, std::size_t>> bad_observations;  // (keyframe index, slot)
};

// Keyframe i: camera at x = spacing * i looking along world +y (body from cam0's T_b_c).
// `bad_every`: every so many observations of keyframes >= 4, the keypoint is moved 30 px.
struct WorldShape {
  int keyframes = kKeyframes;
  int points = 400;
  double spacing = 1.0;  // metres between keyframes
};

std::unique_ptr<World> make_world(int bad_every, const WorldShape& shape = {}) {
  auto w = std::make_unique<World>();
  w->map = w->atlas.create_map();
  const CameraCalibration calib = test::euroc_cam0();
  w->camera = make_camera(calib);
  w->bf = 0.110 * calib.fx;
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> x(-2.5, shape.spacing * (shape.keyframes - 1) + 2.5), y(3.0, 6.0),
      z(-1.5, 1.5);
  std::uniform_int_distribution<int> level(0, 3);

  std::vector<std::shared_ptr<MapPoint>> points;
  for (int j = 0; j < shape.points; ++j) {
    MapPointData d;
    d.p_w = Eigen::Vector3d(x(rng), y(rng), z(rng));
    points.push_back(w->map->new_map_point(d));
    w->true_p_w[points.back()->id()] = d.p_w;
  }
  Eigen::Matrix3d R_w_c;
  R_w_c << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // camera x = world x, y = world -z, z = world y
  int observation = 0;
  for (int i = 0; i < shape.keyframes; ++i) {
    const Pose3 T_w_c(Eigen::Quaterniond(R_w_c), Eigen::Vector3d(shape.spacing * i, 0.0, 0.0));
    KeyFrameData data;
    data.T_b_c = calib.T_b_c;
    data.T_w_b = T_w_c * calib.T_b_c.inverse();
    std::vector<std::pair<std::size_t, std::shared_ptr<MapPoint>>> seen;
    for (const auto& mp : points) {
      const Eigen::Vector3d p_c = T_w_c.inverse() * w->true_p_w[mp->id()];
      Eigen::Vector2d uv;
      if (!w->camera->project(p_c, &uv) || !w->camera->in_image(uv, 5.0)) continue;
      Keypoint kp;
      kp.level = level(rng);
      const bool bad = bad_every > 0 && i >= 4 && ++observation % bad_every == 0;
      kp.uv = (uv + (bad ? Eigen::Vector2d(30.0, -20.0) : Eigen::Vector2d::Zero())).cast<float>();
      if (bad) w->bad_observations.emplace_back(static_cast<std::size_t>(i), data.features.keypoints.size());
      seen.emplace_back(data.features.keypoints.size(), mp);
      data.features.keypoints.push_back(kp);
      data.depth.push_back(static_cast<float>(p_c.z()));
      data.u_right.push_back(static_cast<float>(uv.x() - w->bf / p_c.z()));
    }
    w->true_T_w_b.push_back(data.T_w_b);
    auto kf = w->map->new_keyframe(std::move(data));
    for (const auto& [slot, mp] : seen) kf->add_observation(slot, mp);
    w->keyframes.push_back(kf);
  }
  for (const auto& kf : w->keyframes) kf->update_connections();
  return w;
}

// Moves every keyframe from index `first` on by ~5 cm / 2 deg and every point by ~5 cm.
void perturb(World& w, std::size_t first) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t i = first; i < w.keyframes.size(); ++i) {
    const Pose3 d(so3_exp(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 2.0 * kDegree / std::sqrt(3.0)),
                  Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.05 / std::sqrt(3.0));
    w.keyframes[i]->set_T_w_b(w.true_T_w_b[i] * d);
  }
  for (const auto& mp : w.map->map_points())
    mp->set_p_w(w.true_p_w[mp->id()] + Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.05 / std::sqrt(3.0));
}

LocalBundleAdjustmentOptions window_of_five() {
  LocalBundleAdjustmentOptions o;
  o.max_covisibles = 4;  // the current keyframe and its 4 best covisibles; the rest is the border
  return o;
}

std::set<MapPointId> points_of(const std::vector<std::shared_ptr<KeyFrame>>& kfs, std::size_t first) {
  std::set<MapPointId> ids;
  for (std::size_t i = first; i < kfs.size(); ++i)
    for (const auto& mp : kfs[i]->map_points()) ids.insert(mp->id());
  return ids;
}

TEST(LocalBundleAdjustment, WindowReturnsToTheTruthAndBadObservationsGo) {
  auto w = make_world(/*bad_every=*/37);
  ASSERT_FALSE(w->bad_observations.empty());
  const auto window = w->keyframes.back()->best_covisibles(4);
  std::set<KeyframeId> window_ids{w->keyframes.back()->id()};
  for (const auto& kf : window) window_ids.insert(kf->id());
  ASSERT_EQ(window_ids, (std::set<KeyframeId>{w->keyframes[3]->id(), w->keyframes[4]->id(), w->keyframes[5]->id(),
                                              w->keyframes[6]->id(), w->keyframes[7]->id()}));
  const std::set<MapPointId> local = points_of(w->keyframes, 3);
  perturb(*w, 3);
  std::vector<Pose3> before;
  for (const auto& kf : w->keyframes) before.push_back(kf->T_w_b());
  std::map<MapPointId, Eigen::Vector3d> p_before;
  for (const auto& mp : w->map->map_points()) p_before[mp->id()] = mp->p_w();

  const LocalBundleAdjustmentStats stats =
      local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf, window_of_five());
  EXPECT_FALSE(stats.stopped);
  EXPECT_EQ(stats.window_keyframes, 5u);
  EXPECT_EQ(stats.fixed_keyframes, 3u);
  EXPECT_EQ(stats.points, local.size());
  EXPECT_EQ(stats.observations_removed, w->bad_observations.size());
  EXPECT_EQ(stats.points_culled, 0u);

  for (std::size_t i = 0; i < 3; ++i) {  // the border is untouched
    EXPECT_EQ(w->keyframes[i]->T_w_b().t, before[i].t);
    EXPECT_EQ(w->keyframes[i]->T_w_b().q.coeffs(), before[i].q.coeffs());
  }
  for (std::size_t i = 3; i < w->keyframes.size(); ++i) {
    EXPECT_LT(translation_distance(w->keyframes[i]->T_w_b(), w->true_T_w_b[i]), 1e-3) << "keyframe " << i;
    EXPECT_LT(rotation_distance(w->keyframes[i]->T_w_b(), w->true_T_w_b[i]), 1e-4) << "keyframe " << i;
  }
  double worst = 0.0;
  for (const auto& mp : w->map->map_points()) {
    if (local.count(mp->id())) {
      worst = std::max(worst, (mp->p_w() - w->true_p_w[mp->id()]).norm());
    } else {
      EXPECT_EQ(mp->p_w(), p_before[mp->id()]) << "point outside the window moved";
    }
  }
  EXPECT_LT(worst, 1e-3);

  for (const auto& [k, slot] : w->bad_observations) {  // both sides of the bad observations are gone
    EXPECT_EQ(w->keyframes[k]->map_point(slot), nullptr);
  }
  std::size_t observations = 0;
  for (const auto& mp : w->map->map_points())
    for (const auto& obs : mp->observations()) {
      ++observations;
      EXPECT_EQ(w->map->keyframe(obs.keyframe)->map_point(obs.slot), mp);
    }
  std::size_t slots = 0;
  for (const auto& kf : w->keyframes) slots += kf->map_points().size();
  EXPECT_EQ(observations, slots);
}

TEST(LocalBundleAdjustment, WithoutBorderTheOldestKeyframeIsFixed) {
  auto w = make_world(0);
  perturb(*w, 1);
  const Pose3 first = w->keyframes[0]->T_w_b();
  const LocalBundleAdjustmentStats stats =
      local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf);  // all covisibles: no border
  EXPECT_EQ(stats.window_keyframes + stats.fixed_keyframes, static_cast<std::size_t>(kKeyframes));
  EXPECT_EQ(stats.fixed_keyframes, 1u);
  EXPECT_EQ(stats.observations_removed, 0u);
  EXPECT_EQ(w->keyframes[0]->T_w_b().t, first.t);
  for (std::size_t i = 1; i < w->keyframes.size(); ++i)
    EXPECT_LT(translation_distance(w->keyframes[i]->T_w_b(), w->true_T_w_b[i]), 1e-3) << "keyframe " << i;
}

// A point behind one of its cameras where the solve starts (after a merge or a
// loop correction moved it) cannot be evaluated; Ceres would end the whole
// solve at its first evaluation. It is left out, and the rest converges.
TEST(LocalBundleAdjustment, APointBehindACameraAtTheStartDoesNotStopTheSolve) {
  auto w = make_world(0);
  perturb(*w, 1);
  const auto& last = w->keyframes.back();
  std::shared_ptr<MapPoint> moved;
  for (const auto& mp : last->map_points())
    if (mp->observations().size() >= 3) {
      moved = mp;
      break;
    }
  ASSERT_NE(moved, nullptr);
  const Pose3 T_w_c = last->T_w_c();
  moved->set_p_w(T_w_c * Eigen::Vector3d(0.0, 0.0, -3.0));  // 3 m behind the newest camera
  const LocalBundleAdjustmentStats stats = local_bundle_adjustment(*w->map, last, *w->camera, w->bf);
  EXPECT_GT(stats.iterations, 0);
  EXPECT_GE(stats.observations_removed, 1u);
  for (std::size_t i = 1; i < w->keyframes.size(); ++i)
    EXPECT_LT(translation_distance(w->keyframes[i]->T_w_b(), w->true_T_w_b[i]), 1e-3) << "keyframe " << i;
}

TEST(LocalBundleAdjustment, StopFlagInterrupts) {
  auto w = make_world(37);
  perturb(*w, 3);
  const Pose3 last = w->keyframes.back()->T_w_b();
  const std::size_t slots_before = w->keyframes.back()->map_points().size();
  std::atomic<bool> stop{true};
  const LocalBundleAdjustmentStats stats =
      local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf, window_of_five(), &stop);
  EXPECT_TRUE(stats.stopped);
  EXPECT_EQ(stats.iterations, 0);
  EXPECT_EQ(stats.observations_removed, 0u);
  EXPECT_EQ(w->keyframes.back()->map_points().size(), slots_before);
  EXPECT_LT(translation_distance(w->keyframes.back()->T_w_b(), last), 1e-12);
}

// Both solvers of the local BA (orbatlas' own Levenberg-Marquardt and Ceres)
// from the same perturbed window with bad observations, stereo and monocular
// (bf 0: two-row residuals): the same algorithm, so the same iterations,
// observations erased and end point (to rounding).
// Both optimise the whole window. What they take is a run's local_ba_ms
// (orbatlas run --stats), not measured here.
TEST(LocalBundleAdjustment, TheOwnSolverEndsWhereCeresEndsAndTimesAreReported) {
  struct Case {
    std::size_t window;
    bool stereo;
  };
  for (const auto& [window, stereo] : {Case{10, true}, Case{20, true}, Case{10, false}}) {
    std::map<bool, std::unique_ptr<World>> worlds;
    std::map<bool, LocalBundleAdjustmentStats> stats;
    for (const bool own : {true, false}) {
      auto& w = worlds[own] = make_world(50, {.keyframes = 40, .points = 4000, .spacing = 0.5});
      perturb(*w, w->keyframes.size() - window);  // the window; the border stays exact
      LocalBundleAdjustmentOptions o;
      o.max_covisibles = window - 1;
      o.own_solver = own;
      const LocalBundleAdjustmentStats s = stats[own] =
          local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, stereo ? w->bf : 0.0, o);
      EXPECT_EQ(s.window_keyframes, window);
      EXPECT_GT(s.iterations, 0);
    }
    EXPECT_EQ(stats[true].observations_removed, stats[false].observations_removed);
    EXPECT_NEAR(stats[true].iterations, stats[false].iterations, 1);
    double pose_gap = 0.0, point_gap = 0.0, pose_error = 0.0;
    const World& own = *worlds[true];
    const World& ceres = *worlds[false];
    for (std::size_t i = 0; i < own.keyframes.size(); ++i) {
      pose_gap = std::max(pose_gap, translation_distance(own.keyframes[i]->T_w_b(), ceres.keyframes[i]->T_w_b()));
      pose_error = std::max(pose_error, translation_distance(own.keyframes[i]->T_w_b(), own.true_T_w_b[i]));
    }
    const auto own_points = own.map->map_points();
    for (const auto& mp : own_points)
      if (const auto other = ceres.map->map_point(mp->id()))
        point_gap = std::max(point_gap, (mp->p_w() - other->p_w()).norm());
    // Measured: 4e-15..7e-15 m (poses), 2e-14..4e-14 m (points), 2.6e-8..4.1e-8 m
    // from the truth; the gaps' bounds leave room for another compiler's rounding.
    EXPECT_LT(pose_gap, 1e-12);
    EXPECT_LT(point_gap, 1e-12);
    EXPECT_LT(pose_error, 1e-7);
  }
}

}  // namespace
}  // namespace orbatlas
