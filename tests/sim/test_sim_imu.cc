// Synthetic IMU against the trajectory it comes from.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "core/geometry/so3.h"
#include "core/sim/euroc_sequences.h"
#include "core/sim/imu_synthesizer.h"
#include "core/sim/imu_vibration.h"
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

// Mean power per band of a sampled signal (one axis), from its discrete
// Fourier transform: the one-sided power spectral density averaged over
// [lo_hz, hi_hz).
double band_density(const std::vector<double>& x, double rate_hz, double lo_hz, double hi_hz) {
  const std::size_t n = x.size();
  double sum = 0.0;
  int bins = 0;
  for (std::size_t k = 1; k < n / 2; ++k) {
    const double hz = rate_hz * static_cast<double>(k) / static_cast<double>(n);
    if (hz < lo_hz || hz >= hi_hz) continue;
    double re = 0.0, im = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      const double phase = 2.0 * M_PI * static_cast<double>(k * j % n) / static_cast<double>(n);
      re += x[j] * std::cos(phase);
      im -= x[j] * std::sin(phase);
    }
    sum += 2.0 * (re * re + im * im) / (rate_hz * static_cast<double>(n));
    ++bins;
  }
  return std::sqrt(sum / bins);
}

// The shaped noise has the density of each band it was asked for (and none
// outside), per axis.
TEST(ImuVibration, ShapedNoiseHasTheRequestedSpectrum) {
  const std::vector<Eigen::Vector3d> density = {{0.1, 0.02, 0.0}, {0.0, 0.05, 0.2}};  // 10-20 Hz, 20-30 Hz
  std::mt19937_64 rng(7);
  const auto noise = sim::shaped_noise(density, 10.0, 10.0, 4000, 200.0, rng);
  ASSERT_EQ(noise.size(), 4000u);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> x;
    for (const auto& v : noise) x.push_back(v[axis]);
    for (int band = 0; band < 2; ++band) {
      const double want = density[band][axis];
      const double got = band_density(x, 200.0, 10.0 + 10.0 * band, 20.0 + 10.0 * band);
      EXPECT_NEAR(got, want, 0.12 * want + 1e-4) << "axis " << axis << " band " << band;
    }
    EXPECT_LT(band_density(x, 200.0, 40.0, 100.0), 1e-4) << "axis " << axis << ": power outside the bands";
  }
}

// The real flights' spectrum: the root mean square it gives above 5 Hz is the
// real MH_05 IMU's in flight (scripts/analysis/imu_spectrum.py: accelerometer 1.00 /
// 0.50 / 0.66 m/s^2, gyro 0.027 / 0.054 / 0.049 rad/s).
TEST(ImuVibration, TheFlightSpectrumHasTheRealMagnitude) {
  const auto& spectrum = sim::euroc_flight_vibration();
  const Eigen::Vector3d accel = spectrum.accel_rms(100.0), gyro = spectrum.gyro_rms(100.0);
  EXPECT_NEAR(accel.x(), 1.00, 0.02);
  EXPECT_NEAR(accel.y(), 0.50, 0.02);
  EXPECT_NEAR(accel.z(), 0.66, 0.02);
  EXPECT_NEAR(gyro.x(), 0.027, 0.001);
  EXPECT_NEAR(gyro.y(), 0.054, 0.001);
  EXPECT_NEAR(gyro.z(), 0.049, 0.001);
}

// MH_01 is set down on the floor 19 s in and takes off 43.6 s in (the real
// IMU's vibration starts then): no vibration while parked, the flight's after.
TEST(ImuVibration, MotorsRunFromTakeOffOnly) {
  const auto& spline = mh01_spline();
  const sim::MotorSchedule motors = sim::motor_schedule(spline);
  EXPECT_NEAR(ns_to_s(motors.takeoff_ns - spline.start_ns()), 43.6, 0.5);
  EXPECT_GT(motors.landing_ns, spline.end_ns());  // MH_01 ends in the air
  EXPECT_EQ(motors.level(spline.start_ns() + s_to_ns(30.0)), 0.0);
  EXPECT_NEAR(motors.level(motors.takeoff_ns - s_to_ns(2.0)), motors.idle_level, 1e-12);
  EXPECT_EQ(motors.level(motors.takeoff_ns + s_to_ns(1.0)), 1.0);

  // The synthesised IMU: with the noise of the ideal model and the vibration
  // on, what differs from the model without vibration is the vibration, nil
  // while parked and of the flight's magnitude in the air.
  sim::ImuSynthesisOptions calm;
  calm.seed = 3;
  sim::ImuSynthesisOptions shaking = calm;
  shaking.errors.vibration = 1.0;
  const TimestampNs t0 = spline.start_ns() + s_to_ns(25.0);
  const sim::SyntheticImu a = sim::synthesize_imu(spline, t0, t0 + s_to_ns(60.0), calm);
  const sim::SyntheticImu b = sim::synthesize_imu(spline, t0, t0 + s_to_ns(60.0), shaking);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  Eigen::Vector3d parked = Eigen::Vector3d::Zero(), flying = Eigen::Vector3d::Zero();
  int n_flying = 0;
  for (std::size_t k = 0; k < a.samples.size(); ++k) {
    const Eigen::Vector3d d = b.samples[k].accel - a.samples[k].accel;
    if (a.samples[k].t_ns < motors.idle_from_ns - kNsPerSecond) parked += d.cwiseAbs2();
    if (a.samples[k].t_ns > motors.takeoff_ns) {
      flying += d.cwiseAbs2();
      ++n_flying;
    }
  }
  EXPECT_EQ(parked.norm(), 0.0);
  const Eigen::Vector3d rms = (flying / n_flying).cwiseSqrt();
  const Eigen::Vector3d want = sim::euroc_flight_vibration().accel_rms(100.0);
  for (int axis = 0; axis < 3; ++axis) EXPECT_NEAR(rms[axis], want[axis], 0.1 * want[axis]) << "axis " << axis;
  EXPECT_EQ(a.states.back().accel_bias, b.states.back().accel_bias) << "the noise must not change with vibration";
}

// The realistic model: biases near the real device's, noise of the densities
// measured on the real IMU (not the calibration's), scale and mounting errors
// of the size asked for, and a clock offset: the sample stamped t is the
// ideal measurement at t - offset.
TEST(ImuSynthesizer, TheRealisticModelHasTheRealDevicesErrors) {
  const auto& spline = mh01_spline();
  sim::ImuSynthesisOptions options;
  options.seed = 11;
  options.errors = sim::realistic_imu_errors();
  options.errors.vibration = 0.0;  // the white noise alone
  const TimestampNs t0 = spline.start_ns() + s_to_ns(60.0);
  const sim::SyntheticImu imu = sim::synthesize_imu(spline, t0, t0 + s_to_ns(30.0), options);
  const auto& first = imu.states.front();
  EXPECT_LT((first.gyro_bias - options.errors.gyro_bias_mean).cwiseAbs().maxCoeff(), 4.0 * 0.002);
  EXPECT_GT(first.gyro_bias.norm(), 0.07);  // the real device's 0.08 rad/s
  EXPECT_GT(first.accel_bias.norm(), 0.03);
  EXPECT_NE(imu.gyro_scale, Eigen::Vector3d::Ones());
  EXPECT_LT((imu.gyro_scale - Eigen::Vector3d::Ones()).cwiseAbs().maxCoeff(), 4.0 * 0.002);
  const double mount_deg = rotation_angle(imu.true_T_b_i.q) * 180.0 / M_PI;
  EXPECT_GT(mount_deg, 0.0);
  EXPECT_LT(mount_deg, 0.25);
  double sq_g = 0.0, sq_a = 0.0;
  for (std::size_t k = 0; k < imu.samples.size(); ++k) {
    const ImuSample ideal = sim::ideal_imu_sample(spline, imu.samples[k].t_ns, imu.true_T_b_i);
    sq_g += (imu.samples[k].gyro - imu.gyro_scale.cwiseProduct(ideal.gyro) - imu.states[k].gyro_bias).squaredNorm();
    sq_a += (imu.samples[k].accel - imu.accel_scale.cwiseProduct(ideal.accel) - imu.states[k].accel_bias).squaredNorm();
  }
  const double n = 3.0 * static_cast<double>(imu.samples.size()), dt = 1.0 / options.calibration.rate_hz;
  EXPECT_NEAR(std::sqrt(sq_g / n) * std::sqrt(dt), 2.7e-4, 0.05 * 2.7e-4);
  EXPECT_NEAR(std::sqrt(sq_a / n) * std::sqrt(dt), 4.5e-3, 0.05 * 4.5e-3);

  sim::ImuSynthesisOptions late;
  late.add_noise = false;
  late.errors.time_offset_s = 0.005;
  const sim::SyntheticImu shifted = sim::synthesize_imu(spline, t0, t0 + kNsPerSecond, late);
  for (std::size_t k = 0; k < shifted.samples.size(); k += 37) {
    const TimestampNs t = shifted.samples[k].t_ns;
    const ImuSample measured = sim::ideal_imu_sample(spline, t - 5'000'000, Pose3());
    EXPECT_LT((shifted.samples[k].gyro - measured.gyro).norm(), 1e-12);
    EXPECT_LT((shifted.samples[k].accel - measured.accel).norm(), 1e-12);
    EXPECT_LT((shifted.states[k].T_w_b.t - spline.pose(t).t).norm(), 1e-12) << "ground truth in the cameras' time";
  }
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
