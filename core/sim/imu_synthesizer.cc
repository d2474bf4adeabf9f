#include "core/sim/imu_synthesizer.h"

#include <cmath>
#include <random>
#include <vector>

#include "core/common/error.h"

namespace orbatlas::sim {

ImuSample ideal_imu_sample(const TrajectorySpline& trajectory, TimestampNs t, const Pose3& T_b_i) {
  return ideal_imu_from_state(trajectory.evaluate(t), t, T_b_i);
}

ImuSample ideal_imu_from_state(const SplineState& s, TimestampNs t, const Pose3& T_b_i) {
  const Eigen::Matrix3d R_w_b = s.T_w_b.rotation();
  const Eigen::Matrix3d R_b_i = T_b_i.rotation();
  // Specific force of the body origin in the body frame.
  Eigen::Vector3d f_b = R_w_b.transpose() * (s.a_w + Eigen::Vector3d(0.0, 0.0, kGravity));
  // Lever arm of an IMU away from the body origin (zero for EuRoC: IMU = body).
  // The angular acceleration term is neglected; T_b_i.t is centimetres at most.
  const Eigen::Vector3d& r = T_b_i.t;
  f_b += s.omega_b.cross(s.omega_b.cross(r));
  ImuSample m;
  m.t_ns = t;
  m.gyro = R_b_i.transpose() * s.omega_b;
  m.accel = R_b_i.transpose() * f_b;
  return m;
}

void ImuSynthesisOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(calibration.rate_hz) && calibration.rate_hz > 0.0,
                 "IMU synthesis: calibration.rate_hz must be a finite value > 0, not " << calibration.rate_hz);
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  ORBATLAS_CHECK(non_negative(calibration.gyro_noise_density),
                 "IMU synthesis: calibration.gyro_noise_density must be >= 0, not " << calibration.gyro_noise_density);
  ORBATLAS_CHECK(non_negative(calibration.gyro_random_walk),
                 "IMU synthesis: calibration.gyro_random_walk must be >= 0, not " << calibration.gyro_random_walk);
  ORBATLAS_CHECK(
      non_negative(calibration.accel_noise_density),
      "IMU synthesis: calibration.accel_noise_density must be >= 0, not " << calibration.accel_noise_density);
  ORBATLAS_CHECK(non_negative(calibration.accel_random_walk),
                 "IMU synthesis: calibration.accel_random_walk must be >= 0, not " << calibration.accel_random_walk);
  ORBATLAS_CHECK(non_negative(initial_gyro_bias_sigma),
                 "IMU synthesis: initial_gyro_bias_sigma must be >= 0, not " << initial_gyro_bias_sigma);
  ORBATLAS_CHECK(non_negative(initial_accel_bias_sigma),
                 "IMU synthesis: initial_accel_bias_sigma must be >= 0, not " << initial_accel_bias_sigma);
  ORBATLAS_CHECK(non_negative(vibration_accel), "IMU synthesis: vibration_accel must be >= 0, not " << vibration_accel);
  ORBATLAS_CHECK(non_negative(vibration_gyro), "IMU synthesis: vibration_gyro must be >= 0, not " << vibration_gyro);
}

SyntheticImu synthesize_imu(const TrajectorySpline& trajectory, TimestampNs first_ns, TimestampNs last_ns,
                            const ImuSynthesisOptions& options) {
  options.check();
  const ImuCalibration& cal = options.calibration;
  const TimestampNs period = s_to_ns(1.0 / cal.rate_hz);
  const double dt = ns_to_s(period);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gauss3 = [&](double sigma) {
    return Eigen::Vector3d(sigma * normal(rng), sigma * normal(rng), sigma * normal(rng));
  };

  Eigen::Vector3d bg = Eigen::Vector3d::Zero(), ba = Eigen::Vector3d::Zero();
  if (options.add_noise) {
    bg = gauss3(options.initial_gyro_bias_sigma);
    ba = gauss3(options.initial_accel_bias_sigma);
  }
  const double gyro_white = cal.gyro_noise_density / std::sqrt(dt);
  const double accel_white = cal.accel_noise_density / std::sqrt(dt);
  const double gyro_walk = cal.gyro_random_walk * std::sqrt(dt);
  const double accel_walk = cal.accel_random_walk * std::sqrt(dt);

  // Vibration: a few fixed sinusoids (frequency, axis, phase) per sensor.
  struct Vibration {
    double hz, phase;
    Eigen::Vector3d axis;
  };
  std::vector<Vibration> accel_vibration, gyro_vibration;
  if (options.vibration_accel > 0.0 || options.vibration_gyro > 0.0) {
    // Its own generator: the noise sequence is the same with or without vibration.
    std::mt19937_64 vib_rng(options.seed ^ 0x5EED0F0D1BULL);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const auto axis = [&] { return Eigen::Vector3d(normal(vib_rng), normal(vib_rng), normal(vib_rng)).normalized(); };
    for (const double hz : {47.3, 83.1, 131.7}) {
      accel_vibration.push_back({hz, 2.0 * M_PI * uni(vib_rng), axis()});
      gyro_vibration.push_back({hz * 1.01, 2.0 * M_PI * uni(vib_rng), axis()});
    }
  }
  const auto vibration = [](const std::vector<Vibration>& v, double amplitude, double ts) {
    Eigen::Vector3d out = Eigen::Vector3d::Zero();
    for (const Vibration& s : v)
      out += amplitude / std::sqrt(3.0) * std::sin(2.0 * M_PI * s.hz * ts + s.phase) * s.axis;
    return out;
  };

  SyntheticImu out;
  for (TimestampNs t = std::max(first_ns, trajectory.start_ns()); t <= std::min(last_ns, trajectory.end_ns());
       t += period) {
    const SplineState s = trajectory.evaluate(t);
    ImuSample m = ideal_imu_from_state(s, t, cal.T_b_i);
    GroundTruthState gt;
    gt.t_ns = t;
    gt.T_w_b = s.T_w_b;
    gt.v_w = s.v_w;
    gt.gyro_bias = bg;
    gt.accel_bias = ba;
    out.states.push_back(gt);
    if (options.add_noise) {
      m.gyro += bg + gauss3(gyro_white);
      m.accel += ba + gauss3(accel_white);
      bg += gauss3(gyro_walk);
      ba += gauss3(accel_walk);
    }
    if (!accel_vibration.empty()) {
      const double ts = ns_to_s(t);
      m.gyro += vibration(gyro_vibration, options.vibration_gyro, ts);
      m.accel += vibration(accel_vibration, options.vibration_accel, ts);
    }
    out.samples.push_back(m);
  }
  return out;
}

}  // namespace orbatlas::sim
