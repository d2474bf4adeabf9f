#include "core/sim/imu_synthesizer.h"

#include <cmath>
#include <random>
#include <vector>

#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "core/sim/imu_vibration.h"

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

void ImuErrorModel::check() const {
  const auto finite = [](double v) { return std::isfinite(v); };
  ORBATLAS_CHECK(finite(gyro_noise_density) && finite(accel_noise_density) && finite(gyro_random_walk) &&
                     finite(accel_random_walk),
                 "IMU errors: the noise densities must be finite (negative: the calibration's)");
  ORBATLAS_CHECK(gyro_bias_mean.allFinite() && accel_bias_mean.allFinite(),
                 "IMU errors: the bias means must be finite");
  ORBATLAS_CHECK(gyro_bias_sigma.allFinite() && gyro_bias_sigma.minCoeff() >= 0.0,
                 "IMU errors: gyro_bias_sigma must be >= 0, not (" << gyro_bias_sigma.transpose() << ")");
  ORBATLAS_CHECK(accel_bias_sigma.allFinite() && accel_bias_sigma.minCoeff() >= 0.0,
                 "IMU errors: accel_bias_sigma must be >= 0, not (" << accel_bias_sigma.transpose() << ")");
  ORBATLAS_CHECK(finite(vibration) && vibration >= 0.0, "IMU errors: vibration must be >= 0, not " << vibration);
  ORBATLAS_CHECK(finite(scale_error) && scale_error >= 0.0 && scale_error < 0.1,
                 "IMU errors: scale_error must be in [0, 0.1), not " << scale_error);
  ORBATLAS_CHECK(finite(extrinsic_rotation_deg) && extrinsic_rotation_deg >= 0.0 && extrinsic_rotation_deg <= 10.0,
                 "IMU errors: extrinsic_rotation_deg must be in [0, 10], not " << extrinsic_rotation_deg);
  ORBATLAS_CHECK(finite(extrinsic_translation_m) && extrinsic_translation_m >= 0.0 && extrinsic_translation_m <= 0.1,
                 "IMU errors: extrinsic_translation_m must be in [0, 0.1], not " << extrinsic_translation_m);
  ORBATLAS_CHECK(finite(time_offset_s) && std::abs(time_offset_s) <= 0.5,
                 "IMU errors: time_offset_s must be within +-0.5 s, not " << time_offset_s);
}

ImuErrorModel ideal_imu_errors() { return ImuErrorModel{}; }

ImuErrorModel realistic_imu_errors() {
  ImuErrorModel e;
  // The real MH_05 and MH_01 IMUs while parked, above 30 Hz (scripts/analysis/imu_spectrum.py):
  // gyro 2.3-5.0e-4, accelerometer 2.7e-3 to 1.1e-2 per axis; the settings say
  // 1.7e-4 and 2.0e-3.
  e.gyro_noise_density = 2.7e-4;
  e.accel_noise_density = 4.5e-3;
  // The real device's biases (EuRoC's ground truth of MH_04, MH_05 and the six
  // Vicon-room flights): their mean and their spread between flights.
  e.gyro_bias_mean = Eigen::Vector3d(-0.0020, 0.0224, 0.0776);
  e.gyro_bias_sigma = Eigen::Vector3d::Constant(0.002);
  e.accel_bias_mean = Eigen::Vector3d(-0.017, 0.106, 0.067);
  e.accel_bias_sigma = Eigen::Vector3d(0.009, 0.042, 0.023);
  e.vibration = 1.0;
  e.scale_error = 0.002;
  e.extrinsic_rotation_deg = 0.05;
  e.extrinsic_translation_m = 0.001;
  return e;
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
  errors.check();
}

namespace {

double or_calibration(double value, double calibrated) { return value >= 0.0 ? value : calibrated; }

}  // namespace

SyntheticImu synthesize_imu(const TrajectorySpline& trajectory, TimestampNs first_ns, TimestampNs last_ns,
                            const ImuSynthesisOptions& options) {
  options.check();
  const ImuCalibration& cal = options.calibration;
  const ImuErrorModel& e = options.errors;
  const TimestampNs period = s_to_ns(1.0 / cal.rate_hz);
  const double dt = ns_to_s(period);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto gauss3 = [&](const Eigen::Vector3d& sigma) {
    return Eigen::Vector3d(sigma.x() * normal(rng), sigma.y() * normal(rng), sigma.z() * normal(rng));
  };

  SyntheticImu out;
  out.true_T_b_i = cal.T_b_i;
  Eigen::Vector3d bg = Eigen::Vector3d::Zero(), ba = Eigen::Vector3d::Zero();
  if (options.add_noise) {
    bg = e.gyro_bias_mean + gauss3(e.gyro_bias_sigma);
    ba = e.accel_bias_mean + gauss3(e.accel_bias_sigma);
    // The calibration errors: their own generator, so that the noise sequence
    // is the same with or without them.
    std::mt19937_64 calib_rng(options.seed ^ 0xCA1EB0A7EDULL);
    std::normal_distribution<double> n01(0.0, 1.0);
    const auto draw3 = [&](double sigma) {
      return Eigen::Vector3d(sigma * n01(calib_rng), sigma * n01(calib_rng), sigma * n01(calib_rng));
    };
    out.gyro_scale += draw3(e.scale_error);
    out.accel_scale += draw3(e.scale_error);
    const Eigen::Vector3d rotation = draw3(e.extrinsic_rotation_deg * M_PI / 180.0);
    const Eigen::Vector3d translation = draw3(e.extrinsic_translation_m);
    if (e.extrinsic_rotation_deg > 0.0 || e.extrinsic_translation_m > 0.0)
      out.true_T_b_i = cal.T_b_i * Pose3(so3_exp(rotation), translation);
  }
  const double gyro_white = or_calibration(e.gyro_noise_density, cal.gyro_noise_density) / std::sqrt(dt);
  const double accel_white = or_calibration(e.accel_noise_density, cal.accel_noise_density) / std::sqrt(dt);
  const double gyro_walk = or_calibration(e.gyro_random_walk, cal.gyro_random_walk) * std::sqrt(dt);
  const double accel_walk = or_calibration(e.accel_random_walk, cal.accel_random_walk) * std::sqrt(dt);

  // What each stamp measured: the motion at stamp - offset.
  const TimestampNs offset = s_to_ns(e.time_offset_s);
  std::vector<TimestampNs> stamps;
  for (TimestampNs t = first_ns; t <= last_ns; t += period)
    if (trajectory.covers(t - offset) && trajectory.covers(t)) stamps.push_back(t);

  // Vibration while the motors run: its own generator, for the same reason.
  std::vector<Eigen::Vector3d> gyro_vibration, accel_vibration;
  MotorSchedule motors;
  if (options.add_noise && e.vibration > 0.0 && !stamps.empty()) {
    std::mt19937_64 vib_rng(options.seed ^ 0x5EED0F0D1BULL);
    const VibrationSpectrum& spectrum = euroc_flight_vibration();
    gyro_vibration =
        shaped_noise(spectrum.gyro, spectrum.first_hz, spectrum.band_hz, stamps.size(), cal.rate_hz, vib_rng);
    accel_vibration =
        shaped_noise(spectrum.accel, spectrum.first_hz, spectrum.band_hz, stamps.size(), cal.rate_hz, vib_rng);
    motors = motor_schedule(trajectory);
  }

  const Eigen::Vector3d white_g = Eigen::Vector3d::Constant(gyro_white),
                        white_a = Eigen::Vector3d::Constant(accel_white);
  const Eigen::Vector3d walk_g = Eigen::Vector3d::Constant(gyro_walk), walk_a = Eigen::Vector3d::Constant(accel_walk);
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    const TimestampNs t = stamps[k];
    const TimestampNs measured = t - offset;
    const SplineState s = trajectory.evaluate(measured);
    ImuSample m = ideal_imu_from_state(s, t, out.true_T_b_i);
    GroundTruthState gt;
    gt.t_ns = t;
    if (offset == 0) {
      gt.T_w_b = s.T_w_b;
      gt.v_w = s.v_w;
    } else {
      const SplineState now = trajectory.evaluate(t);
      gt.T_w_b = now.T_w_b;
      gt.v_w = now.v_w;
    }
    gt.gyro_bias = bg;
    gt.accel_bias = ba;
    out.states.push_back(gt);
    if (options.add_noise) {
      m.gyro = out.gyro_scale.cwiseProduct(m.gyro) + bg + gauss3(white_g);
      m.accel = out.accel_scale.cwiseProduct(m.accel) + ba + gauss3(white_a);
      bg += gauss3(walk_g);
      ba += gauss3(walk_a);
    }
    if (!gyro_vibration.empty()) {
      const double level = e.vibration * motors.level(measured);
      m.gyro += level * gyro_vibration[k];
      m.accel += level * accel_vibration[k];
    }
    out.samples.push_back(m);
  }
  return out;
}

}  // namespace orbatlas::sim
