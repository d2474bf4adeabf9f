// Synthetic IMU against the trajectory it comes from.
#include <gtest/gtest.h>

#include "core/geometry/so3.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/trajectory_spline.h"

namespace orbatlas {
namespace {

const sim::TrajectorySpline& mh01_spline() {
  static const sim::TrajectorySpline spline(sim::load_ground_truth(sim::find_sequence("MH_01")));
  return spline;
}

TEST(TrajectorySpline, FollowsTheRealGroundTruth) {
  const Trajectory gt = sim::load_ground_truth(sim::find_sequence("MH_01"));
  const auto& spline = mh01_spline();
  double max_err = 0, sum_sq = 0;
  int n = 0;
  for (std::size_t i = 0; i < gt.size(); i += 50) {
    if (!spline.covers(gt[i].t_ns)) continue;
    const double e = (spline.pose(gt[i].t_ns).t - gt[i].pose.t).norm();
    max_err = std::max(max_err, e);
    sum_sq += e * e;
    ++n;
  }
  ASSERT_GT(n, 500);
  EXPECT_LT(std::sqrt(sum_sq / n), 0.005) << "smoothing moved the trajectory too far";
  EXPECT_LT(max_err, 0.03);
}

TEST(TrajectorySpline, AnalyticDerivativesMatchFiniteDifferences) {
  const auto& spline = mh01_spline();
  const TimestampNs h = 100'000;  // 0.1 ms
  for (TimestampNs t = spline.start_ns() + kNsPerSecond; t < spline.end_ns() - kNsPerSecond;
       t += 7 * kNsPerSecond + 12345) {
    const sim::SplineState s = spline.evaluate(t);
    const sim::SplineState a = spline.evaluate(t - h), b = spline.evaluate(t + h);
    const double dt = 2e-9 * static_cast<double>(h);
    EXPECT_LT((s.v_w - (b.T_w_b.t - a.T_w_b.t) / dt).norm(), 1e-5);
    EXPECT_LT((s.a_w - (b.v_w - a.v_w) / dt).norm(), 1e-3);
    const Eigen::Vector3d omega_fd = so3_log(a.T_w_b.q.conjugate() * b.T_w_b.q) / dt;
    EXPECT_LT((s.omega_b - omega_fd).norm(), 1e-5);
  }
}

// Integrates noise-free IMU over 1 s from the true state; must land on the truth.
TEST(ImuSynthesizer, IntegratingOneSecondReproducesTheMotion) {
  const auto& spline = mh01_spline();
  sim::ImuSynthesisOptions options;
  options.add_noise = false;
  for (const double offset_s : {20.0, 60.0, 110.0}) {
    const TimestampNs t0 = spline.start_ns() + s_to_ns(offset_s);
    const sim::SyntheticImu imu = sim::synthesize_imu(spline, t0, t0 + kNsPerSecond, options);
    ASSERT_EQ(imu.samples.size(), 201u);
    const sim::SplineState start = spline.evaluate(t0);
    Eigen::Quaterniond q = start.T_w_b.q;
    Eigen::Vector3d p = start.T_w_b.t, v = start.v_w;
    const Eigen::Vector3d g(0, 0, -sim::kGravity);
    for (std::size_t k = 0; k + 1 < imu.samples.size(); ++k) {
      const ImuSample& m0 = imu.samples[k];
      const ImuSample& m1 = imu.samples[k + 1];
      const double dt = ns_to_s(m1.t_ns - m0.t_ns);
      const Eigen::Quaterniond q1 = q * so3_exp(0.5 * (m0.gyro + m1.gyro) * dt);
      const Eigen::Vector3d a0 = q * m0.accel + g, a1 = q1 * m1.accel + g;
      p += v * dt + (2.0 * a0 + a1) / 6.0 * dt * dt;
      v += 0.5 * (a0 + a1) * dt;
      q = q1;
    }
    const Pose3 truth = spline.pose(t0 + kNsPerSecond);
    EXPECT_LT((p - truth.t).norm(), 0.002) << "position after 1 s at offset " << offset_s;
    EXPECT_LT(rotation_angle(q.conjugate() * truth.q) * 180.0 / M_PI, 0.02) << "rotation after 1 s";
  }
}

TEST(ImuSynthesizer, NoiseHasTheRequestedDensity) {
  const auto& spline = mh01_spline();
  sim::ImuSynthesisOptions options;
  options.seed = 42;
  const TimestampNs t0 = spline.start_ns() + 10 * kNsPerSecond;
  const sim::SyntheticImu noisy = sim::synthesize_imu(spline, t0, t0 + 50 * kNsPerSecond, options);
  double sum_sq_g = 0, sum_sq_a = 0;
  const std::size_t n = noisy.samples.size();
  for (std::size_t k = 0; k < n; ++k) {
    const ImuSample ideal = sim::ideal_imu_sample(spline, noisy.samples[k].t_ns, options.calibration.T_b_i);
    sum_sq_g += (noisy.samples[k].gyro - ideal.gyro - noisy.states[k].gyro_bias).squaredNorm();
    sum_sq_a += (noisy.samples[k].accel - ideal.accel - noisy.states[k].accel_bias).squaredNorm();
  }
  const double dt = 1.0 / options.calibration.rate_hz;
  EXPECT_NEAR(std::sqrt(sum_sq_g / (3.0 * n)), options.calibration.gyro_noise_density / std::sqrt(dt),
              0.05 * options.calibration.gyro_noise_density / std::sqrt(dt));
  EXPECT_NEAR(std::sqrt(sum_sq_a / (3.0 * n)), options.calibration.accel_noise_density / std::sqrt(dt),
              0.05 * options.calibration.accel_noise_density / std::sqrt(dt));
  // Biases wander but stay plausible.
  EXPECT_GT((noisy.states.back().gyro_bias - noisy.states.front().gyro_bias).norm(), 0.0);
}

// The real look's vibration: with the noise off, what it adds is exactly the
// vibration, whose power is that of three sinusoids of amplitude A/sqrt(3)
// (mean square A^2/2 over the three axes together); the noise sequence is the
// same with or without it.
TEST(ImuSynthesizer, VibrationAddsSinusoidsOfTheRequestedAmplitude) {
  const auto& spline = mh01_spline();
  const TimestampNs t0 = spline.start_ns() + 10 * kNsPerSecond;
  sim::ImuSynthesisOptions quiet;
  quiet.add_noise = false;
  sim::ImuSynthesisOptions shaking = quiet;
  shaking.vibration_accel = 0.3;
  shaking.vibration_gyro = 0.02;
  const sim::SyntheticImu a = sim::synthesize_imu(spline, t0, t0 + 20 * kNsPerSecond, quiet);
  const sim::SyntheticImu b = sim::synthesize_imu(spline, t0, t0 + 20 * kNsPerSecond, shaking);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  double sq_a = 0, sq_g = 0;
  for (std::size_t k = 0; k < a.samples.size(); ++k) {
    sq_a += (b.samples[k].accel - a.samples[k].accel).squaredNorm();
    sq_g += (b.samples[k].gyro - a.samples[k].gyro).squaredNorm();
  }
  const double n = static_cast<double>(a.samples.size());
  EXPECT_NEAR(std::sqrt(sq_a / n), 0.3 / std::sqrt(2.0), 0.3 * 0.15);
  EXPECT_NEAR(std::sqrt(sq_g / n), 0.02 / std::sqrt(2.0), 0.02 * 0.15);
  // With noise on, the noise itself is unchanged by the vibration.
  sim::ImuSynthesisOptions noisy, noisy_shaking;
  noisy_shaking.vibration_accel = 0.3;
  const sim::SyntheticImu c = sim::synthesize_imu(spline, t0, t0 + kNsPerSecond, noisy);
  const sim::SyntheticImu d = sim::synthesize_imu(spline, t0, t0 + kNsPerSecond, noisy_shaking);
  EXPECT_EQ(c.states.back().accel_bias, d.states.back().accel_bias);
}

TEST(ImuSynthesizer, GravityAtRestPointsUpInTheBody) {
  Trajectory still;
  for (int i = 0; i < 400; ++i) still.push_back({i * 5'000'000LL, Pose3()});
  const sim::TrajectorySpline spline(still);
  const ImuSample m = sim::ideal_imu_sample(spline, spline.start_ns() + kNsPerSecond / 2, Pose3());
  EXPECT_LT((m.accel - Eigen::Vector3d(0, 0, sim::kGravity)).norm(), 1e-9);
  EXPECT_LT(m.gyro.norm(), 1e-9);
}

}  // namespace
}  // namespace orbatlas
