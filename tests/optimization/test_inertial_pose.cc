// Visual-inertial pose optimisation against exact synthetic data: two
// frames 50 ms apart on the real MH_01 trajectory (the simulator's spline), the
// ideal IMU between them, and exact projections of random points into the
// EuRoC camera at the second frame.
#include <gtest/gtest.h>

#include <random>

#include "core/camera/camera_factory.h"
#include "core/geometry/so3.h"
#include "core/optimization/inertial_cost.h"
#include "core/optimization/level_sigma.h"
#include "core/optimization/pose_optimizer.h"
#include "core/optimization/pose_parameters.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"
#include "tests/support/sim_test_helpers.h"

namespace orbatlas {
namespace {

const Eigen::Vector3d kGravity(0.0, 0.0, -sim::kGravity);

const sim::TrajectorySpline& mh01_spline() {
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  return spline;
}

// The camera in the body (EuRoC's cam0 is about this far from the IMU, which is the body).
Pose3 camera_in_body() {
  return Pose3(so3_exp(Eigen::Vector3d(0.02, -0.01, 1.55)), Eigen::Vector3d(-0.02, -0.06, 0.01));
}

struct TwoFrames {
  Pose3 T_w_b0, T_w_b1;  // truth
  Eigen::Vector3d v0, v1;
  std::shared_ptr<const Preintegration> increments;
};

TwoFrames two_frames(double at_s) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + s_to_ns(at_s) + 1'234'567, t1 = t0 + 50'000'000;
  sim::ImuSynthesisOptions o;
  o.add_noise = false;
  const sim::SyntheticImu imu = sim::synthesize_imu(spline, t0 - 20'000'000, t1 + 20'000'000, o);
  TwoFrames f;
  const sim::SplineState s0 = spline.evaluate(t0), s1 = spline.evaluate(t1);
  f.T_w_b0 = s0.T_w_b;
  f.T_w_b1 = s1.T_w_b;
  f.v0 = s0.v_w;
  f.v1 = s1.v_w;
  f.increments =
      std::make_shared<const Preintegration>(Preintegration::between(imu.samples, t0, t1, ImuBias{}, ImuNoise{}));
  return f;
}

PoseOptimizerInput stereo_view(const Camera& camera, const Pose3& T_c_w, std::mt19937& rng) {
  PoseOptimizerInput input;
  input.bf = 0.11 * camera.calibration().fx;
  const Pose3 T_w_c = T_c_w.inverse();
  std::uniform_real_distribution<double> u(20.0, camera.width() - 20.0), v(20.0, camera.height() - 20.0);
  std::uniform_real_distribution<double> range(1.0, 12.0);
  while (input.correspondences.size() < 300) {
    const Eigen::Vector3d p_c = camera.unproject(Eigen::Vector2d(u(rng), v(rng))) * range(rng);
    Eigen::Vector2d uv;
    if (!camera.project(p_c, &uv)) continue;
    PoseCorrespondence c;
    c.p_w = T_w_c * p_c;
    c.uv = uv;
    c.u_right = uv.x() - input.bf / p_c.z();
    input.correspondences.push_back(c);
  }
  return input;
}

InertialPoseTerm inertial_term(const TwoFrames& f, const Pose3& T_b_c) {
  InertialPoseTerm term;
  term.increments = f.increments;
  term.T_c_i = T_b_c.inverse();  // the IMU is the body
  term.gravity_w = kGravity;
  term.previous_T_c_w = (f.T_w_b0 * T_b_c).inverse();
  term.previous_v_w = f.v0;
  term.previous_covariance = StateCovariance::Identity() * 1e-6;
  term.v_w = f.v0;  // the start: as if the frame moved on at the last frame's velocity
  term.bias_sigma.setConstant(1e-3);
  return term;
}

TEST(InertialCost, IsThePreintegrationResidualWeightedByItsInformation) {
  const TwoFrames f = two_frames(30.0);
  const Pose3 T_b_c = camera_in_body();
  const auto cost = make_inertial_cost(f.increments, T_b_c.inverse(), kGravity);
  // States a little off the truth, and biases off the linearisation point.
  const Pose3 T_c_w0 = (f.T_w_b0 * T_b_c).inverse();
  const Pose3 T_c_w1 =
      (Pose3(so3_exp(Eigen::Vector3d(0.003, -0.002, 0.001)) * f.T_w_b1.q, f.T_w_b1.t + Eigen::Vector3d(0.01, 0, 0)) *
       T_b_c)
          .inverse();
  const Eigen::Vector3d v0 = f.v0 + Eigen::Vector3d(0.02, 0.0, -0.01), v1 = f.v1;
  ImuBias bias;
  bias.gyro = Eigen::Vector3d(0.001, -0.002, 0.0005);
  bias.accel = Eigen::Vector3d(0.02, 0.01, -0.03);
  const PoseParameters p0 = PoseParameters::from_pose(T_c_w0), p1 = PoseParameters::from_pose(T_c_w1);
  Eigen::Matrix<double, 6, 1> b;
  b << bias.gyro, bias.accel;
  const double* params[7] = {p0.q.data(), p0.t.data(), v0.data(), p1.q.data(), p1.t.data(), v1.data(), b.data()};
  Eigen::Matrix<double, 9, 1> weighted;
  ASSERT_TRUE(cost->Evaluate(params, weighted.data(), nullptr));

  auto imu_state = [](const Pose3& T_w_b, const Eigen::Vector3d& v) {
    return ImuState{T_w_b.q.toRotationMatrix(), T_w_b.t, v};
  };
  const Preintegration::Vector9 r =
      f.increments->residual(imu_state(T_c_w0.inverse() * T_b_c.inverse(), v0),
                             imu_state(T_c_w1.inverse() * T_b_c.inverse(), v1), bias, kGravity);
  const double chi2 = r.dot(f.increments->covariance().inverse() * r);
  EXPECT_GT(chi2, 1.0);
  EXPECT_NEAR(weighted.squaredNorm(), chi2, 1e-6 * chi2);
}

TEST(InertialPoseOptimizer, RecoversThePoseAndTheVelocityFromAPerturbedStart) {
  const auto camera = make_camera(test::euroc_cam0());
  const Pose3 T_b_c = camera_in_body();
  std::mt19937 rng(7);
  for (const double at_s : {45.0, 70.0, 120.0}) {
    const TwoFrames f = two_frames(at_s);
    const Pose3 T_c_w1 = (f.T_w_b1 * T_b_c).inverse();
    PoseOptimizerInput input = stereo_view(*camera, T_c_w1, rng);
    input.T_c_w = (Pose3(so3_exp(Eigen::Vector3d(0.01, 0.0, -0.01)) * f.T_w_b1.q,
                         f.T_w_b1.t + Eigen::Vector3d(0.03, -0.02, 0.01)) *
                   T_b_c)
                      .inverse();
    input.inertial = inertial_term(f, T_b_c);
    const PoseOptimizerResult result = optimize_pose(*camera, input);
    ASSERT_TRUE(result.inertial.has_value());
    const Pose3 T_w_b = result.T_c_w.inverse() * T_b_c.inverse();
    const double position_error = (T_w_b.t - f.T_w_b1.t).norm();
    const double velocity_error = (result.inertial->v_w - f.v1).norm();
    const double velocity_sigma =
        result.inertial->covariance ? std::sqrt(result.inertial->covariance->diagonal().tail<3>().maxCoeff()) : -1.0;
    EXPECT_EQ(result.inlier_count, 300);
    EXPECT_LT(position_error, 8e-6);                                    // measured at most 3.8e-6 m
    EXPECT_LT(rotation_angle(T_w_b.q.conjugate() * f.T_w_b1.q), 3e-6);  // 1.4e-6 rad
    EXPECT_LT(velocity_error, 2.5e-5);                                  // 1.2e-5 m/s
    EXPECT_LT(result.inertial->chi2, 3e-6);                             // measured at most 1.1e-6
    ASSERT_TRUE(result.inertial->covariance.has_value());
    // The velocity is known to about what the IMU over 50 ms and the last
    // frame's prior (1 mm/s) allow: 1.1 mm/s measured.
    EXPECT_LT(velocity_sigma, 2.5e-3);
  }
}

TEST(InertialPoseOptimizer, TakesTheVelocityThePositionsImplyOverAWrongPrior) {
  // The last frame's velocity prior is 0.1 m/s off, but loose (0.2 m/s): the
  // two positions 50 ms apart and the IMU between them say what it was.
  const auto camera = make_camera(test::euroc_cam0());
  const Pose3 T_b_c = camera_in_body();
  std::mt19937 rng(11);
  const TwoFrames f = two_frames(60.0);
  const Pose3 T_c_w1 = (f.T_w_b1 * T_b_c).inverse();
  PoseOptimizerInput input = stereo_view(*camera, T_c_w1, rng);
  input.T_c_w = T_c_w1;
  InertialPoseTerm term = inertial_term(f, T_b_c);
  term.previous_v_w = f.v0 + Eigen::Vector3d(0.1, 0.0, 0.0);
  term.previous_covariance.diagonal().tail<3>().setConstant(0.2 * 0.2);
  term.v_w = term.previous_v_w;
  input.inertial = term;
  const PoseOptimizerResult result = optimize_pose(*camera, input);
  ASSERT_TRUE(result.inertial.has_value());
  const double error = (result.inertial->v_w - f.v1).norm();
  EXPECT_LT(error, 3.5e-3);  // measured 1.8e-3 m/s (the 0.1 m/s prior pulls a little)
}

}  // namespace
}  // namespace orbatlas
