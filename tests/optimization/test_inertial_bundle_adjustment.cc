// Visual-inertial local bundle adjustment against exact synthetic
// data: twelve stereo keyframes 0.25 s apart on the real MH_01 trajectory (the
// simulator's spline), exact projections of points into the EuRoC camera, and
// the ideal IMU with a constant bias between consecutive keyframes,
// preintegrated at that bias. The anchor (the keyframe before the temporal
// window) holds its true state; the window starts off in pose, velocity and
// biases, and must come back to the truth. The same world serves the full
// (global) visual-inertial BA and the map's inertial initialisation.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <map>
#include <random>

#include "core/camera/camera_factory.h"
#include "core/geometry/so3.h"
#include "core/imu/turn_about_gravity.h"
#include "core/mapping/inertial_initializer.h"
#include "core/map/atlas.h"
#include "core/optimization/apply_global_adjustment.h"
#include "core/optimization/inertial_cost.h"
#include "core/optimization/local_bundle_adjustment.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

constexpr int kKeyframes = 12;
constexpr double kSpacingS = 0.25;
const Eigen::Vector3d kGravity(0.0, 0.0, -sim::kGravity);

ImuBias true_bias() {
  ImuBias b;
  b.gyro = Eigen::Vector3d(0.004, -0.002, 0.003);
  b.accel = Eigen::Vector3d(0.05, -0.03, 0.02);
  return b;
}

struct InertialWorld {
  Atlas atlas;
  std::shared_ptr<Map> map;
  std::unique_ptr<Camera> camera;
  double bf = 0.0;
  std::vector<std::shared_ptr<KeyFrame>> keyframes;
  std::vector<Pose3> true_T_w_b;
  std::vector<Pose3> T_b_i;  // each keyframe's IMU in its body
  std::vector<Eigen::Vector3d> true_v_w;
  std::map<MapPointId, Eigen::Vector3d> true_p_w;
  std::vector<ImuSample> imu;  // what the links were preintegrated from
};

// The body is the IMU (T_b_i identity, as EuRoC's). With `second_session_from`
// the keyframes from there on are another session's: its chain starts there
// (no link to the keyframe before); with `second_body_is_camera` that session's
// body is its camera (a single camera's), so its keyframes' poses are the
// camera's and its IMU sits at T_c_i in the body. Every link carries the IMU in
// its camera unless `links_place_imu` is false (links stored before schema 8).
struct WorldOptions {
  std::size_t second_session_from = 0;
  bool second_body_is_camera = false;
  bool links_place_imu = true;
  // A single camera's keyframes: no depths (the map's scale is free).
  bool no_depths = false;
  // The IMU's scale factors (each measurement less its bias is these times the true one).
  Eigen::Vector3d gyro_factor = Eigen::Vector3d::Ones(), accel_factor = Eigen::Vector3d::Ones();
};
std::unique_ptr<InertialWorld> make_world(double at_s, const WorldOptions& wo) {
  auto w = std::make_unique<InertialWorld>();
  w->map = w->atlas.create_map();
  const CameraCalibration calib = test::euroc_cam0();
  w->camera = make_camera(calib);
  w->bf = 0.110 * calib.fx;
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  const TimestampNs t0 = spline.start_ns() + s_to_ns(at_s);
  std::vector<TimestampNs> times;
  std::vector<Pose3> T_b_c;  // each keyframe's camera in its body
  for (int i = 0; i < kKeyframes; ++i) {
    times.push_back(t0 + s_to_ns(kSpacingS * i));
    const sim::SplineState s = spline.evaluate(times.back());
    const bool camera_body =
        wo.second_body_is_camera && wo.second_session_from > 0 && static_cast<std::size_t>(i) >= wo.second_session_from;
    T_b_c.push_back(camera_body ? Pose3() : calib.T_b_c);
    w->T_b_i.push_back(camera_body ? calib.T_b_c.inverse() : Pose3());
    w->true_T_w_b.push_back(s.T_w_b * w->T_b_i.back().inverse());
    w->true_v_w.push_back(s.v_w);
  }

  // Points: random pixels of every keyframe at 2-8 m; each observed by every
  // keyframe it projects into.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(20.0, calib.width - 20.0), v(20.0, calib.height - 20.0), depth(2.0, 8.0);
  std::vector<std::shared_ptr<MapPoint>> points;
  for (int i = 0; i < kKeyframes; ++i) {
    const Pose3 T_w_c = w->true_T_w_b[static_cast<std::size_t>(i)] * T_b_c[static_cast<std::size_t>(i)];
    for (int j = 0; j < 40; ++j) {
      MapPointData d;
      d.p_w = T_w_c * (w->camera->unproject(Eigen::Vector2d(u(rng), v(rng))) * depth(rng));
      points.push_back(w->map->new_map_point(d));
      w->true_p_w[points.back()->id()] = d.p_w;
    }
  }
  for (int i = 0; i < kKeyframes; ++i) {
    const Pose3 T_w_c = w->true_T_w_b[static_cast<std::size_t>(i)] * T_b_c[static_cast<std::size_t>(i)];
    KeyFrameData data;
    data.timestamp_ns = times[static_cast<std::size_t>(i)];
    data.T_b_c = T_b_c[static_cast<std::size_t>(i)];
    data.T_w_b = w->true_T_w_b[static_cast<std::size_t>(i)];
    std::vector<std::pair<std::size_t, std::shared_ptr<MapPoint>>> seen;
    for (const auto& mp : points) {
      const Eigen::Vector3d p_c = T_w_c.inverse() * w->true_p_w[mp->id()];
      Eigen::Vector2d uv;
      if (p_c.z() < 0.5 || !w->camera->project(p_c, &uv) || !w->camera->in_image(uv, 5.0)) continue;
      Keypoint kp;
      kp.uv = uv.cast<float>();
      seen.emplace_back(data.features.keypoints.size(), mp);
      data.features.keypoints.push_back(kp);
      data.depth.push_back(wo.no_depths ? -1.0f : static_cast<float>(p_c.z()));
      data.u_right.push_back(wo.no_depths ? -1.0f : static_cast<float>(uv.x() - w->bf / p_c.z()));
    }
    auto kf = w->map->new_keyframe(std::move(data));
    for (const auto& [slot, mp] : seen) kf->add_observation(slot, mp);
    w->keyframes.push_back(kf);
  }
  for (const auto& kf : w->keyframes) kf->update_connections();

  // The ideal IMU plus a constant bias, preintegrated at that bias.
  sim::ImuSynthesisOptions o;
  o.add_noise = false;
  sim::SyntheticImu imu = sim::synthesize_imu(spline, times.front() - 20'000'000, times.back() + 20'000'000, o);
  for (ImuSample& s : imu.samples) {
    s.gyro = wo.gyro_factor.cwiseProduct(s.gyro) + true_bias().gyro;
    s.accel = wo.accel_factor.cwiseProduct(s.accel) + true_bias().accel;
  }
  const std::optional<Pose3> T_c_i = wo.links_place_imu ? std::optional<Pose3>(calib.T_b_c.inverse()) : std::nullopt;
  for (std::size_t i = 1; i < w->keyframes.size(); ++i)
    if (i != wo.second_session_from)
      w->keyframes[i]->set_inertial_link(w->keyframes[i - 1],
                                         std::make_shared<const Preintegration>(Preintegration::between(
                                             imu.samples, times[i - 1], times[i], true_bias(), ImuNoise{})),
                                         T_c_i);
  for (std::size_t i = 0; i < w->keyframes.size(); ++i)
    w->keyframes[i]->set_imu_state(
        KeyFrame::ImuState{(w->true_T_w_b[i] * w->T_b_i[i]).q.conjugate() * w->true_v_w[i], true_bias()});
  w->imu = std::move(imu.samples);
  return w;
}

LocalBundleAdjustmentOptions inertial_options(const InertialWorld& w) {
  LocalBundleAdjustmentOptions o;
  o.max_covisibles = 0;  // the window is the temporal one; the other observers are the border
  o.inertial =
      InertialWindowOptions{.T_b_i = Pose3(), .gravity_w = kGravity, .map_bias = ImuBias{}, .temporal_keyframes = 10};
  o.origin = w.keyframes.front()->id();
  return o;
}

// The window (the last ten keyframes) is moved by ~1 cm / 0.3 deg, its
// velocities by 5 cm/s and its biases to zero; the points by ~1 cm.
void perturb(InertialWorld& w) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  for (std::size_t i = 2; i < w.keyframes.size(); ++i) {
    const Pose3 d(so3_exp(Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.003),
                  Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.01);
    w.keyframes[i]->set_T_w_b(w.true_T_w_b[i] * d);
    const Eigen::Vector3d v_w = w.true_v_w[i] + Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.05;
    w.keyframes[i]->set_imu_state(
        KeyFrame::ImuState{(w.keyframes[i]->T_w_b() * w.T_b_i[i]).q.conjugate() * v_w, ImuBias{}});
  }
  for (const auto& mp : w.map->map_points())
    mp->set_p_w(w.true_p_w[mp->id()] + Eigen::Vector3d(n(rng), n(rng), n(rng)) * 0.01);
}

struct Errors {
  double position = 0.0, rotation = 0.0, velocity = 0.0, gyro_bias = 0.0, accel_bias = 0.0;
};

Errors window_errors(const InertialWorld& w) {
  Errors e;
  for (std::size_t i = 2; i < w.keyframes.size(); ++i) {
    const Pose3 T = w.keyframes[i]->T_w_b();
    const auto state = w.keyframes[i]->imu_state();
    e.position = std::max(e.position, (T.t - w.true_T_w_b[i].t).norm());
    e.rotation = std::max(e.rotation, so3_log(w.true_T_w_b[i].q.conjugate() * T.q).norm());
    e.velocity = std::max(e.velocity, ((T * w.T_b_i[i]).q * state->v_i - w.true_v_w[i]).norm());
    e.gyro_bias = std::max(e.gyro_bias, (state->bias.gyro - true_bias().gyro).norm());
    e.accel_bias = std::max(e.accel_bias, (state->bias.accel - true_bias().accel).norm());
  }
  return e;
}

TEST(InertialBundleAdjustment, TheWindowReturnsToTheTrueStatesAndBiases) {
  for (const double at_s : {45.0, 90.0}) {
    auto w = make_world(at_s, {});
    perturb(*w);
    const LocalBundleAdjustmentStats stats =
        local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf, inertial_options(*w));
    const Errors after = window_errors(*w);
    EXPECT_EQ(stats.inertial_keyframes, 11u);  // the anchor and the ten of the window
    EXPECT_EQ(stats.inertial_edges, 10u);
    EXPECT_EQ(stats.window_keyframes, 10u);
    EXPECT_EQ(stats.observations_removed, 0u);
    // Measured: position 3.0e-5 m, rotation 5.8e-6 rad, velocity 2.6e-5 m/s,
    // gyro bias 3.1e-8 rad/s, accelerometer bias 2.8e-5 m/s^2, chi2 1.1e-3
    // (the preintegration's discretisation of the spline at 200 Hz).
    EXPECT_LT(after.position, 6e-5);
    EXPECT_LT(after.rotation, 1.2e-5);
    EXPECT_LT(after.velocity, 5.5e-5);
    EXPECT_LT(after.gyro_bias, 7e-8);
    EXPECT_LT(after.accel_bias, 6e-5);
    EXPECT_LT(stats.inertial_chi2_max, 2.2e-3);
  }
}

// An IMU whose scale factors are off (1 % on the accelerometer's horizontal
// axes, as a poor MEMS part's): with its scale correction as an unknown, the
// window finds it and comes back to the truth; held at none, the factors pull
// the window off.
TEST(InertialBundleAdjustment, TheWindowFindsTheImusScaleFactors) {
  WorldOptions wo;
  wo.gyro_factor = Eigen::Vector3d(1.002, 0.998, 1.003);
  wo.accel_factor = Eigen::Vector3d(1.0, 1.01, 0.99);
  const Eigen::Vector3d true_accel = wo.accel_factor.cwiseInverse() - Eigen::Vector3d::Ones();
  const Eigen::Vector3d true_gyro = wo.gyro_factor.cwiseInverse() - Eigen::Vector3d::Ones();
  std::map<bool, Errors> errors;
  for (const bool estimated : {false, true}) {
    SCOPED_TRACE(estimated ? "estimated" : "held");
    auto w = make_world(45.0, wo);
    perturb(*w);
    LocalBundleAdjustmentOptions o = inertial_options(*w);
    o.inertial->scale_sigma = estimated ? 0.02 : 0.0;
    o.second_iterations = 20;
    const LocalBundleAdjustmentStats stats =
        local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf, o);
    errors[estimated] = window_errors(*w);
    if (estimated) {
      // Measured: position 2.4e-5 m, rotation 8.4e-6 rad, velocity 9.2e-5 m/s;
      // the gyro's correction within 9.4e-5 of the truth on every axis, the
      // accelerometer's 1.6e-5 on its z axis, which the window's motion
      // excites (its y axis, little excited here, stays half-way: -0.0033 of
      // -0.0099, the rest in the bias).
      EXPECT_LT(errors[true].position, 5e-5);
      EXPECT_LT(errors[true].rotation, 1.7e-5);
      EXPECT_LT(errors[true].velocity, 2e-4);
      EXPECT_LT((stats.imu_scale.gyro - true_gyro).cwiseAbs().maxCoeff(), 2e-4);
      EXPECT_NEAR(stats.imu_scale.accel.z(), true_accel.z(), 4e-5);
      EXPECT_LT(stats.inertial_chi2_max, 0.021);  // measured 0.0104
      // What the window told of the correction: measured 4e5-1.2e6 on the
      // gyro's axes and the accelerometer's x, 4.6e4 on its z and 1.4e3 on
      // its y (the axis it left half-way).
      const ImuScaleInformation& info = stats.imu_scale_information;
      EXPECT_GT(info.diagonal().head<4>().minCoeff(), 1.9e5);
      EXPECT_GT(info(5, 5), 2.3e4);
      EXPECT_LT(info(4, 4), 2.8e3);
      EXPECT_GE(Eigen::SelfAdjointEigenSolver<ImuScaleInformation>(info).eigenvalues().minCoeff(), 0.0);
    } else {
      // Measured: position 1.7e-3 m, velocity 1.8e-3 m/s, chi2 up to 76.
      EXPECT_GT(errors[false].position, 1e-3);
      EXPECT_GT(stats.inertial_chi2_max, 38.0);
      EXPECT_TRUE(stats.imu_scale == ImuScaleCorrection{});  // held
      EXPECT_TRUE(stats.imu_scale_information.isZero());
    }
  }
}

// Both solvers of the visual-inertial local BA (orbatlas' own
// Levenberg-Marquardt with the inertial edges, bias walks and anchor, and
// Ceres) from the same perturbed window: the same algorithm, so the same end
// point (to rounding): poses, velocities, biases, points.
// Rounding differs between machines (the same build ends 100 times further
// apart on CI's), so the bounds are set by what rounding can move, not by
// this machine's gaps.
// With covisible keyframes beside the chain (a window of 10 and 20).
TEST(InertialBundleAdjustment, TheOwnSolverEndsWhereCeresEnds) {
  for (const std::size_t covisibles : {std::size_t{0}, std::size_t{10}}) {
    SCOPED_TRACE("covisibles " + std::to_string(covisibles));
    std::map<bool, std::unique_ptr<InertialWorld>> worlds;
    std::map<bool, LocalBundleAdjustmentStats> stats;
    for (const bool own : {true, false}) {
      auto& w = worlds[own] = make_world(45.0, {});
      perturb(*w);
      LocalBundleAdjustmentOptions o = inertial_options(*w);
      o.max_covisibles = covisibles;
      o.own_solver = own;
      stats[own] = local_bundle_adjustment(*w->map, w->keyframes.back(), *w->camera, w->bf, o);
      EXPECT_EQ(stats[own].inertial_edges, 10u);
      EXPECT_GT(stats[own].iterations, 0);
    }
    EXPECT_EQ(stats[true].window_keyframes, stats[false].window_keyframes);
    EXPECT_EQ(stats[true].observations_removed, stats[false].observations_removed);
    // Not the same count of iterations: near the end a step's decrease sits at
    // the stopping tolerance, where rounding decides (13 or 15 here, as the
    // binary's layout changes); the end points below are what must agree.
    for (const bool own : {true, false}) EXPECT_LE(stats[own].iterations, 15);
    const InertialWorld& own = *worlds[true];
    const InertialWorld& ceres = *worlds[false];
    double pose_gap = 0.0, velocity_gap = 0.0, bias_gap = 0.0, point_gap = 0.0;
    for (std::size_t i = 0; i < own.keyframes.size(); ++i) {
      pose_gap = std::max(pose_gap, (own.keyframes[i]->T_w_b().t - ceres.keyframes[i]->T_w_b().t).norm());
      const auto a = own.keyframes[i]->imu_state(), b = ceres.keyframes[i]->imu_state();
      velocity_gap = std::max(velocity_gap, (a->v_i - b->v_i).norm());
      bias_gap = std::max(bias_gap, (a->bias.gyro - b->bias.gyro).norm() + (a->bias.accel - b->bias.accel).norm());
    }
    for (const auto& mp : own.map->map_points())
      if (const auto other = ceres.map->map_point(mp->id()))
        point_gap = std::max(point_gap, (mp->p_w() - other->p_w()).norm());
    // Measured here: poses 5e-15 m, velocities 1e-14 m/s, biases 8e-15,
    // points 5e-14 m, and 8.2e-6 m from the truth. The gaps are rounding
    // carried through a weakly seen point's flat direction: shifting one
    // solver's start by 1e-13 m gives 4e-13 m, 3e-13 m/s, 1e-12 and 3e-10 m,
    // and on CI's machine they were 1e-10 m, 6e-11 m/s, 2e-10 and 4.6e-8 m. The bounds sit at about five times that and
    // a thousandth of the distance to the truth: a wrong term in either solver moves the end point by micrometres.
    EXPECT_LT(pose_gap, 5e-10);
    EXPECT_LT(velocity_gap, 5e-10);
    EXPECT_LT(bias_gap, 1e-9);
    EXPECT_LT(point_gap, 2e-7);
    EXPECT_LT(window_errors(own).position, 2e-5);
  }
}

// ORB-SLAM3's FullInertialBA as local mapping runs it after an initialisation
// or refinement: the global BA with the inertial chain, applied to the map (in
// gravity -z; the map's oldest keyframe fixes the gauge).
GlobalBundleAdjustmentResult full_inertial_ba(InertialWorld& w, double huber = std::sqrt(kChi2Inertial95)) {
  Map::InertialState state;
  state.gravity_w = kGravity;
  w.map->set_inertial_state(state);
  GlobalBundleAdjustmentOptions options;
  options.iterations = 20;
  options.inertial =
      GlobalBundleAdjustmentOptions::Inertial{.T_b_i = Pose3(), .max_chain_keyframes = 200, .huber = huber};
  GlobalBundleAdjustmentResult result = global_bundle_adjustment(*w.map, *w.camera, w.bf, options);
  const GlobalAdjustmentApplyStats applied = apply_global_adjustment(*w.map, result, ScalePyramid{});
  EXPECT_FALSE(applied.stale);
  EXPECT_EQ(applied.imu_states_set, result.imu_states.size());
  return result;
}

// Every keyframe and point of the map and the whole chain's IMU states.
TEST(InertialBundleAdjustment, TheFullBundleAdjustmentReturnsEveryStateToTheTruth) {
  auto w = make_world(45.0, {});
  perturb(*w);
  const GlobalBundleAdjustmentResult stats = full_inertial_ba(*w);
  const Errors after = window_errors(*w);
  EXPECT_FALSE(stats.stopped);
  EXPECT_EQ(stats.keyframes, static_cast<std::size_t>(kKeyframes));
  EXPECT_EQ(stats.imu_states.size(), static_cast<std::size_t>(kKeyframes));
  EXPECT_EQ(stats.inertial_keyframes, static_cast<std::size_t>(kKeyframes));
  EXPECT_EQ(stats.inertial_edges, static_cast<std::size_t>(kKeyframes - 1));
  EXPECT_EQ(stats.points, w->true_p_w.size());
  EXPECT_LT((w->keyframes.front()->T_w_b().t - w->true_T_w_b.front().t).norm(), 1e-12);  // the gauge, kept
  // Measured: position 1.1e-5 m (from 2.6e-2), rotation 6.4e-6 rad, velocity
  // 2.6e-5 m/s (from 0.18), gyro bias 7.5e-7 rad/s, accelerometer bias 3.1e-5
  // m/s^2 (from 6.2e-2), chi2 3.9e-4.
  EXPECT_LT(after.position, 2.2e-5);
  EXPECT_LT(after.rotation, 1.3e-5);
  EXPECT_LT(after.velocity, 5.2e-5);
  EXPECT_LT(after.gyro_bias, 1.5e-6);
  EXPECT_LT(after.accel_bias, 6.2e-5);
  EXPECT_LT(stats.inertial_chi2_max, 8e-4);
}

// A map two visual-inertial sessions built (merged): two inertial chains, the
// second starting at keyframe 6 with no link to the first. Both keep their IMU
// terms and return to the truth, not only the newest session's.
TEST(InertialBundleAdjustment, TheFullBundleAdjustmentKeepsEverySessionsChain) {
  auto w = make_world(45.0, {.second_session_from = 6});
  perturb(*w);
  const GlobalBundleAdjustmentResult stats = full_inertial_ba(*w);
  const Errors after = window_errors(*w);
  EXPECT_EQ(stats.inertial_chains, 2u);
  EXPECT_EQ(stats.inertial_keyframes, static_cast<std::size_t>(kKeyframes));
  EXPECT_EQ(stats.inertial_edges, static_cast<std::size_t>(kKeyframes - 2));
  EXPECT_EQ(stats.imu_states.size(), static_cast<std::size_t>(kKeyframes));
  // Measured: position 1.1e-5 m, rotation 4.1e-6 rad, velocity 5.8e-5 m/s,
  // gyro bias 5.4e-6 rad/s, accelerometer bias 9.2e-5 m/s^2 (two 1.25-s
  // chains pin the biases less than one of 2.75 s); the first session's
  // velocities started 0.18 m/s off.
  EXPECT_LT(after.position, 2.2e-5);
  EXPECT_LT(after.rotation, 8.5e-6);
  EXPECT_LT(after.velocity, 1.2e-4);
  EXPECT_LT(after.gyro_bias, 1.1e-5);
  EXPECT_LT(after.accel_bias, 1.8e-4);
}

// A map a stereo-inertial rig (body: its IMU) and a single camera with its IMU
// (body: its camera) built: the full BA takes the first's IMU-in-body, and the
// second chain's links place their IMU in the camera themselves, so both
// return to the truth. Links without it (stored before schema 8) would put the
// camera session's IMU at the camera: its chain is bent (measured below).
TEST(InertialBundleAdjustment, EachChainPlacesItsOwnImuWhenTheSessionsBodiesDiffer) {
  const auto run = [](bool links_place_imu) {
    auto w =
        make_world(45.0, {.second_session_from = 6, .second_body_is_camera = true, .links_place_imu = links_place_imu});
    perturb(*w);
    const GlobalBundleAdjustmentResult stats = full_inertial_ba(*w);
    const Errors after = window_errors(*w);
    EXPECT_EQ(stats.inertial_chains, 2u);
    return after;
  };
  const Errors placed = run(true);
  // Measured: as the two sessions of one body (the test above).
  EXPECT_LT(placed.position, 2.2e-5);
  EXPECT_LT(placed.rotation, 8.5e-6);
  EXPECT_LT(placed.velocity, 1.2e-4);
  EXPECT_LT(placed.gyro_bias, 1.1e-5);
  EXPECT_LT(placed.accel_bias, 1.8e-4);
  const Errors legacy = run(false);
  // Measured without: position 2.2e-2 m, velocity 0.34 m/s, accel bias 13 m/s^2.
  EXPECT_GT(legacy.position, 100.0 * placed.position);
  EXPECT_GT(legacy.velocity, 100.0 * placed.velocity);
}

// One link the IMU and the images disagree on (its samples 0.3 m/s^2 off for
// 0.25 s: 9 mm of displacement): the Huber kernel on the inertial terms lets
// it bend the map less; without it every keyframe moves towards it.
TEST(InertialBundleAdjustment, TheFullBundleAdjustmentResistsALinkTheImagesContradict) {
  const auto max_position_error = [](double huber) {
    auto w = make_world(45.0, {});
    const std::size_t bad = 6;
    std::vector<ImuSample> samples = w->imu;
    for (ImuSample& s : samples) s.accel += Eigen::Vector3d(0.3, 0.0, 0.0);
    const TimestampNs t0 = w->keyframes[bad - 1]->timestamp_ns(), t1 = w->keyframes[bad]->timestamp_ns();
    w->keyframes[bad]->set_inertial_link(
        w->keyframes[bad - 1],
        std::make_shared<const Preintegration>(Preintegration::between(samples, t0, t1, true_bias(), ImuNoise{})),
        w->keyframes[bad]->inertial_link()->T_c_i);
    full_inertial_ba(*w, huber);
    double error = 0.0;
    for (std::size_t i = 0; i < w->keyframes.size(); ++i)
      error = std::max(error, (w->keyframes[i]->T_w_b().t - w->true_T_w_b[i].t).norm());
    return error;
  };
  const double robust = max_position_error(std::sqrt(kChi2Inertial95));
  const double plain = max_position_error(0.0);
  // Measured: 4.0e-3 m with the kernel (the bad link's chi2 left at 404),
  // 5.5e-3 m without (chi2 38: the error spread over the map).
  EXPECT_LT(robust, 8e-3);
  EXPECT_LT(robust, 0.85 * plain);
}

// The map's inertial initialisation, with links preintegrated at zero biases
// (as a session makes them before it) and a gyro bias of 0.019 rad/s: the
// initialisation finds the bias, and every link (first-order corrected only
// until then) is integrated again at it, as ORB-SLAM3 does past 0.01 rad/s.
TEST(InertialBundleAdjustment, TheMapsInitialisationIntegratesFarLinksAgainAtTheBiasFound) {
  const Eigen::Vector3d extra_gyro(0.015, 0.0, 0.0);
  std::vector<ImuSample> samples;
  const auto world_linked_at_zero_bias = [&] {
    auto w = make_world(45.0, {});
    samples = w->imu;
    for (ImuSample& s : samples) s.gyro += extra_gyro;
    for (std::size_t i = 1; i < w->keyframes.size(); ++i)
      w->keyframes[i]->set_inertial_link(
          w->keyframes[i - 1],
          std::make_shared<const Preintegration>(Preintegration::between(
              samples, w->keyframes[i - 1]->timestamp_ns(), w->keyframes[i]->timestamp_ns(), ImuBias{}, ImuNoise{})),
          w->keyframes[i]->inertial_link()->T_c_i);
    return w;
  };
  auto w = world_linked_at_zero_bias();
  InertialInitializationOptions options;
  options.enabled = true;
  const auto state = initialize_map_inertial(*w->map, w->keyframes.back(), options);
  ASSERT_TRUE(state.has_value());
  const Eigen::Vector3d true_gyro = true_bias().gyro + extra_gyro;
  EXPECT_LT((state->bias.gyro - true_gyro).norm(), 3e-6);  // measured 1.4e-6 rad/s
  for (std::size_t i = 1; i < w->keyframes.size(); ++i) {
    const Preintegration& link = *w->keyframes[i]->inertial_link()->from_previous;
    EXPECT_EQ(link.bias().gyro, state->bias.gyro) << "link " << i << " was not integrated again";
    const Preintegration exact = Preintegration::between(samples, w->keyframes[i - 1]->timestamp_ns(),
                                                         w->keyframes[i]->timestamp_ns(), state->bias, ImuNoise{});
    EXPECT_LT(so3_log(Eigen::Quaterniond(exact.delta_R(state->bias).transpose() * link.delta_R(state->bias))).norm(),
              1e-12);
    EXPECT_LT((exact.delta_p(state->bias) - link.delta_p(state->bias)).norm(), 1e-12);
  }
  // A bias change under the threshold keeps the links as they are.
  options.reintegrate_gyro_bias_change = 1.0;
  auto kept = world_linked_at_zero_bias();
  ASSERT_TRUE(initialize_map_inertial(*kept->map, kept->keyframes.back(), options).has_value());
  EXPECT_EQ(kept->keyframes.back()->inertial_link()->from_previous->bias().gyro, Eigen::Vector3d::Zero());
}

// The initialisation turns the map so that gravity points along -z, about its
// newest keyframe: that keyframe (where a device tracked in the map is) stays
// where it was, and the map comes out as the true one up to a turn about
// gravity and a shift. The map starts tilted by 20 deg about a point 30 m away.
TEST(InertialBundleAdjustment, TheInitialisationTurnsTheMapAboutItsNewestKeyframe) {
  auto w = make_world(45.0, {});
  const Pose3 tilt(
      Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * M_PI / 180.0, Eigen::Vector3d(1.0, 1.0, 0.0).normalized())),
      Eigen::Vector3d(30.0, 0.0, 0.0));
  w->map->change_frame(tilt);
  const Eigen::Vector3d newest_before = w->keyframes.back()->T_w_b().t;
  InertialInitializationOptions options;
  options.enabled = true;
  ASSERT_TRUE(initialize_map_inertial(*w->map, w->keyframes.back(), options).has_value());
  const double moved = (w->keyframes.back()->T_w_b().t - newest_before).norm();
  // The turn from the true frame to the map's: about gravity only.
  double tilt_deg = 0.0, shape_m = 0.0;
  const Pose3 T_map_true = w->keyframes.back()->T_w_b() * w->true_T_w_b.back().inverse();
  for (std::size_t i = 0; i < w->keyframes.size(); ++i) {
    const Pose3 T = w->keyframes[i]->T_w_b() * w->true_T_w_b[i].inverse();
    tilt_deg =
        std::max(tilt_deg, std::acos(std::clamp((T.q * Eigen::Vector3d::UnitZ()).z(), -1.0, 1.0)) * 180.0 / M_PI);
    shape_m = std::max(shape_m, (w->keyframes[i]->T_w_b().t - T_map_true * w->true_T_w_b[i].t).norm());
  }
  EXPECT_LT(moved, 1e-9);
  EXPECT_LT(tilt_deg, 0.5);  // measured 0.26 (the accelerometer bias under its prior)
  EXPECT_LT(shape_m, 1e-9);
}

// A refinement re-estimates gravity (and a monocular map's scale) over the
// newest keyframe's chain and applies it to the whole map. After a merge or a
// late join that chain is a few seconds of another session: the map, estimated
// over a longer window, is left as it is; over a chain as long, it is refined.
TEST(InertialBundleAdjustment, ARefinementOverAChainShorterThanTheMapsEstimateLeavesTheMapAlone) {
  InertialInitializationOptions options;
  options.enabled = true;
  options.refinements = {{0.5, 1.0, 1e5}};
  const auto initialised = [&](std::unique_ptr<InertialWorld>& w) {
    const double span_s = ns_to_s(w->keyframes.back()->timestamp_ns() - w->keyframes.front()->timestamp_ns());
    Map::InertialState state;
    state.initialized_at_ns = w->keyframes.front()->timestamp_ns();
    state.gravity_w = kGravity;  // the world is gravity aligned already
    state.keyframes = w->keyframes.size();
    state.span_s = span_s;
    w->map->set_inertial_state(state);
  };
  // The newest keyframe's chain: the last five of twelve (1 s of 2.75 s).
  auto w = make_world(45.0, {.second_session_from = 7});
  initialised(w);
  const Pose3 before = w->keyframes.front()->T_w_b();
  EXPECT_FALSE(refine_map_inertial(*w->map, w->keyframes.back(), options).has_value());
  const auto kept = w->map->inertial_state();
  ASSERT_TRUE(kept.has_value());
  EXPECT_EQ(kept->refinements, 1u);  // tried, not waited for
  EXPECT_EQ(kept->keyframes, w->keyframes.size());
  EXPECT_EQ(w->keyframes.front()->T_w_b().t, before.t);
  EXPECT_EQ(w->keyframes.front()->T_w_b().q.coeffs(), before.q.coeffs());

  // The whole chain: refined, and the state says over which window.
  auto whole = make_world(45.0, {});
  initialised(whole);
  const auto refined = refine_map_inertial(*whole->map, whole->keyframes.back(), options);
  ASSERT_TRUE(refined.has_value());
  EXPECT_EQ(refined->refinements, 1u);
  EXPECT_EQ(refined->keyframes, whole->keyframes.size());
  EXPECT_NEAR(refined->span_s, 2.75, 1e-9);
  // With the rule off the short chain is used.
  options.refinement_min_span_fraction = 0.0;
  auto short_chain = make_world(45.0, {.second_session_from = 7});
  initialised(short_chain);
  const auto forced = refine_map_inertial(*short_chain->map, short_chain->keyframes.back(), options);
  ASSERT_TRUE(forced.has_value());
  EXPECT_EQ(forced->keyframes, 5u);
}

// Until the rig has turned about gravity, a horizontal accelerometer bias and a
// tilt of gravity are one measurement: a refinement that would free the bias
// keeps it held under the 5-s refinement's prior (its tilt goes to gravity, as
// at the initialisation), and frees it once the chain has turned far enough.
TEST(InertialBundleAdjustment, ARefinementFreesTheAccelerometerBiasOnlyOnceTheRigHasTurned) {
  std::vector<Eigen::Matrix3d> R_w_i;
  {
    auto w = make_world(45.0, {});
    for (std::size_t i = 0; i < w->true_T_w_b.size(); ++i)
      R_w_i.push_back((w->true_T_w_b[i] * w->T_b_i[i]).q.toRotationMatrix());
  }
  const double turned_deg = turn_about_gravity_deg(R_w_i, kGravity);
  ASSERT_GT(turned_deg, 1.0);  // MH_01 45-47.75 s
  const auto refine = [&](double min_turn_deg, double accel_bias_prior = 0.0, bool single_camera = false) {
    auto w = make_world(45.0, {.no_depths = single_camera});
    Map::InertialState state;
    state.initialized_at_ns = w->keyframes.front()->timestamp_ns();
    state.gravity_w = kGravity;
    state.keyframes = w->keyframes.size();
    state.span_s = ns_to_s(w->keyframes.back()->timestamp_ns() - w->keyframes.front()->timestamp_ns());
    w->map->set_inertial_state(state);
    InertialInitializationOptions options;
    options.enabled = true;
    options.refinements = {{0.5, 0.0, accel_bias_prior}};  // both biases free unless told
    options.min_turn_to_free_accel_bias_deg = min_turn_deg;
    options.solver.estimate_scale = single_camera;
    return refine_map_inertial(*w->map, w->keyframes.back(), options);
  };
  const auto tilt_deg = [](const Map::InertialState& s) {
    return std::acos(std::clamp(s.gravity_w.normalized().dot(kGravity.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
  };
  // Held: the estimate the 5-s refinement's prior gives, its bias partly in the tilt.
  const auto held = refine(turned_deg + 1.0);
  const auto with_prior = refine(turned_deg + 1.0, InertialInitializationOptions{}.held_accel_bias_prior);
  ASSERT_TRUE(held.has_value() && with_prior.has_value());
  EXPECT_LT((held->bias.accel - with_prior->bias.accel).norm(), 1e-12);
  EXPECT_GT((held->bias.accel - true_bias().accel).norm(), 0.02);  // measured 0.045 m/s^2
  EXPECT_GT(tilt_deg(*held), 0.13);                                // measured 0.26 degrees
  // Freed: on exact data the bias and gravity come back.
  const auto freed = refine(turned_deg - 1.0);
  ASSERT_TRUE(freed.has_value());
  EXPECT_LT((freed->bias.accel - true_bias().accel).norm(), 1e-3);  // measured 3.6e-4 m/s^2
  EXPECT_LT(tilt_deg(*freed), 0.005);                               // measured 0.0021 degrees
  // A single camera's map (its scale estimated too) is not held: the same
  // estimate whatever the turn asked for.
  const auto single = refine(turned_deg + 1.0, 0.0, true);
  const auto single_freed = refine(turned_deg - 1.0, 0.0, true);
  ASSERT_TRUE(single.has_value() && single_freed.has_value());
  EXPECT_LT((single->bias.accel - single_freed->bias.accel).norm(), 1e-12);
  EXPECT_LT((single->bias.accel - true_bias().accel).norm(), 1e-3);
}

TEST(InertialBundleAdjustment, BiasWalkCostIsTheDifferenceOverTheWalkSigma) {
  ImuNoise noise;
  const double dt = 0.2;
  const auto cost = make_bias_walk_cost(noise, dt);
  Eigen::Matrix<double, 6, 1> b1, b2;
  b1 << 0.001, 0.002, -0.001, 0.01, 0.02, -0.03;
  b2 = b1;
  b2[1] += 1e-5;
  b2[4] -= 1e-3;
  const double* params[2] = {b1.data(), b2.data()};
  Eigen::Matrix<double, 6, 1> r;
  ASSERT_TRUE(cost->Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[1], 1e-5 / std::sqrt(noise.gyro_walk_variance(dt)), 1e-9);
  EXPECT_NEAR(r[4], -1e-3 / std::sqrt(noise.accel_walk_variance(dt)), 1e-9);
  EXPECT_NEAR(r[0], 0.0, 1e-12);
}

}  // namespace
}  // namespace orbatlas
