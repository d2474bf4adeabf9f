#include "core/imu/preintegration.h"

#include <algorithm>
#include <cmath>
#include <Eigen/Geometry>

#include "core/common/error.h"
#include "core/geometry/so3.h"
#include "core/imu/inertial_residual.h"

namespace orbatlas {
namespace {

Eigen::Matrix3d exp_matrix(const Eigen::Vector3d& w) { return so3_exp(w).toRotationMatrix(); }

Eigen::Matrix3d normalized(const Eigen::Matrix3d& R) { return Eigen::Quaterniond(R).normalized().toRotationMatrix(); }

ImuSample lerp(const ImuSample& a, const ImuSample& b, TimestampNs t) {
  const double s = static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  ImuSample out;
  out.t_ns = t;
  out.gyro = (1.0 - s) * a.gyro + s * b.gyro;
  out.accel = (1.0 - s) * a.accel + s * b.accel;
  return out;
}

}  // namespace

Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& w) {
  const double theta = w.norm();
  const Eigen::Matrix3d W = hat(w);
  if (theta < 1e-5) return Eigen::Matrix3d::Identity() - 0.5 * W;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

Preintegration::Preintegration(const ImuBias& bias, const ImuNoise& noise) : noise_(noise), bias_(bias) {
  noise_.check();
}

Preintegration Preintegration::between(const std::vector<ImuSample>& samples, TimestampNs t0, TimestampNs t1,
                                       const ImuBias& bias, const ImuNoise& noise, double max_gap_s) {
  ORBATLAS_CHECK(t1 > t0, "imu: preintegration needs t1 > t0 (" << t0 << " ns, " << t1 << " ns)");
  const auto max_gap_ns = static_cast<TimestampNs>(max_gap_s * 1e9);
  // The newest sample may end up to max_gap before t1: it holds until then (below).
  ORBATLAS_DATA_CHECK(
      samples.size() >= 2 && samples.front().t_ns <= t0 && samples.back().t_ns >= t1 - max_gap_ns,
      "imu: the samples do not cover " << format_seconds_exact(t0) << " .. " << format_seconds_exact(t1) << " s");
  Preintegration out(bias, noise);
  // The last sample at or before t0.
  auto it = std::upper_bound(samples.begin(), samples.end(), t0,
                             [](TimestampNs t, const ImuSample& s) { return t < s.t_ns; });
  std::size_t k = static_cast<std::size_t>(std::distance(samples.begin(), it)) - 1;
  for (; k + 1 < samples.size() && samples[k].t_ns < t1; ++k) {
    const ImuSample& a = samples[k];
    const ImuSample& b = samples[k + 1];
    ORBATLAS_DATA_CHECK(b.t_ns > a.t_ns,
                        "imu: sample times do not increase at " << format_seconds_exact(a.t_ns) << " s");
    ORBATLAS_DATA_CHECK(b.t_ns - a.t_ns <= max_gap_ns, "imu: a gap of " << static_cast<double>(b.t_ns - a.t_ns) * 1e-9
                                                                        << " s after " << format_seconds_exact(a.t_ns)
                                                                        << " s (at most " << max_gap_s << " s)");
    const TimestampNs from = std::max(t0, a.t_ns), to = std::min(t1, b.t_ns);
    if (to <= from) continue;
    const ImuSample start = lerp(a, b, from), end = lerp(a, b, to);
    out.integrate(0.5 * (start.gyro + end.gyro), 0.5 * (start.accel + end.accel),
                  static_cast<double>(to - from) * 1e-9);
  }
  // A frame just after the newest sample (a live stream's next IMU batch is on
  // its way): the newest sample holds until t1.
  const ImuSample& last = samples.back();
  if (last.t_ns < t1) out.integrate(last.gyro, last.accel, static_cast<double>(t1 - std::max(t0, last.t_ns)) * 1e-9);
  return out;
}

void Preintegration::reset(const ImuBias& bias) {
  bias_ = bias;
  dt_ = 0.0;
  delta_R_.setIdentity();
  delta_v_.setZero();
  delta_p_.setZero();
  covariance_.setZero();
  dR_dbg_.setZero();
  dv_dbg_.setZero();
  dv_dba_.setZero();
  dp_dbg_.setZero();
  dp_dba_.setZero();
  dR_dsg_.setZero();
  dv_dsg_.setZero();
  dv_dsa_.setZero();
  dp_dsg_.setZero();
  dp_dsa_.setZero();
}

void Preintegration::integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt) {
  ORBATLAS_CHECK(std::isfinite(dt) && dt > 0.0, "imu: a measurement must last > 0 s, not " << dt);
  ORBATLAS_DATA_CHECK(gyro.allFinite() && accel.allFinite(), "imu: a measurement is not finite");
  measurements_.push_back({gyro, accel, dt});
  propagate(measurements_.back());
}

void Preintegration::propagate(const Measurement& m) {
  const double dt = m.dt, dt2 = dt * dt;
  const Eigen::Vector3d w = m.gyro - bias_.gyro;
  const Eigen::Vector3d a = m.accel - bias_.accel;
  const Eigen::Matrix3d dR = exp_matrix(w * dt);
  const Eigen::Matrix3d Jr = so3_right_jacobian(w * dt);
  // The specific force is rotated with the rotation at the middle of the
  // interval (ORB-SLAM3 takes the start's, which leaves an error of about
  // |f| |w| dt / 2 per step: millimetres per second at 200 Hz).
  const Eigen::Matrix3d dR_half = exp_matrix(0.5 * w * dt);
  const Eigen::Matrix3d R_mid = delta_R_ * dR_half;
  const Eigen::Matrix3d Jr_half = so3_right_jacobian(0.5 * w * dt);
  const Eigen::Matrix3d dRmid_dbg = dR_half.transpose() * dR_dbg_ - Jr_half * (0.5 * dt);
  // A scale correction moves the rate by diag(w) where a bias moves it by -I.
  const Eigen::Matrix3d W_diag = w.asDiagonal(), A_diag = a.asDiagonal();
  const Eigen::Matrix3d dRmid_dsg = dR_half.transpose() * dR_dsg_ + Jr_half * W_diag * (0.5 * dt);
  const Eigen::Matrix3d Ra = R_mid * hat(a);

  // Covariance of the error state (rotation, velocity, position), before the
  // increments move on. A rotation error d at the start moves the middle
  // rotation by dR_half^T d.
  Matrix9 A = Matrix9::Identity();
  A.block<3, 3>(0, 0) = dR.transpose();
  A.block<3, 3>(3, 0) = -Ra * dR_half.transpose() * dt;
  A.block<3, 3>(6, 0) = -0.5 * Ra * dR_half.transpose() * dt2;
  A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
  Eigen::Matrix<double, 9, 3> Bg = Eigen::Matrix<double, 9, 3>::Zero(), Ba = Eigen::Matrix<double, 9, 3>::Zero();
  Bg.block<3, 3>(0, 0) = Jr * dt;
  Ba.block<3, 3>(3, 0) = R_mid * dt;
  Ba.block<3, 3>(6, 0) = 0.5 * R_mid * dt2;
  covariance_ = A * covariance_ * A.transpose() + noise_.gyro_variance(dt) * Bg * Bg.transpose() +
                noise_.accel_variance(dt) * Ba * Ba.transpose();

  // Bias Jacobians (position first: it uses the velocity's previous ones).
  dp_dba_ += dv_dba_ * dt - 0.5 * R_mid * dt2;
  dp_dbg_ += dv_dbg_ * dt - 0.5 * Ra * dRmid_dbg * dt2;
  dv_dba_ -= R_mid * dt;
  dv_dbg_ -= Ra * dRmid_dbg * dt;
  dp_dsa_ += dv_dsa_ * dt + 0.5 * R_mid * A_diag * dt2;
  dp_dsg_ += dv_dsg_ * dt - 0.5 * Ra * dRmid_dsg * dt2;
  dv_dsa_ += R_mid * A_diag * dt;
  dv_dsg_ -= Ra * dRmid_dsg * dt;

  // Increments.
  delta_p_ += delta_v_ * dt + 0.5 * R_mid * a * dt2;
  delta_v_ += R_mid * a * dt;
  delta_R_ = normalized(delta_R_ * dR);
  dR_dbg_ = dR.transpose() * dR_dbg_ - Jr * dt;
  dR_dsg_ = dR.transpose() * dR_dsg_ + Jr * W_diag * dt;
  dt_ += dt;
}

void Preintegration::reintegrate(const ImuBias& bias) {
  reset(bias);
  for (const Measurement& m : measurements_) propagate(m);
}

void Preintegration::append(const Preintegration& next) {
  for (const Measurement& m : next.measurements_) {
    measurements_.push_back(m);
    propagate(m);
  }
}

Eigen::Matrix3d Preintegration::delta_R(const ImuBias& bias, const ImuScaleCorrection& scale) const {
  return normalized(delta_R_ * exp_matrix(dR_dbg_ * (bias.gyro - bias_.gyro) + dR_dsg_ * scale.gyro));
}

Eigen::Vector3d Preintegration::delta_v(const ImuBias& bias, const ImuScaleCorrection& scale) const {
  return delta_v_ + dv_dbg_ * (bias.gyro - bias_.gyro) + dv_dba_ * (bias.accel - bias_.accel) + dv_dsg_ * scale.gyro +
         dv_dsa_ * scale.accel;
}

Eigen::Vector3d Preintegration::delta_p(const ImuBias& bias, const ImuScaleCorrection& scale) const {
  return delta_p_ + dp_dbg_ * (bias.gyro - bias_.gyro) + dp_dba_ * (bias.accel - bias_.accel) + dp_dsg_ * scale.gyro +
         dp_dsa_ * scale.accel;
}

Preintegration::Matrix9 Preintegration::covariance() const {
  const ImuVibration& v = noise_.vibration;
  if (v.rotation_var.isZero() && v.velocity_var.isZero()) return covariance_;
  // The rotation residual is in the end's IMU frame (the start's error turned
  // by the increment), the velocity residual in the start's (the end's turned).
  const Eigen::Matrix3d R_diag = v.rotation_var.asDiagonal(), V_diag = v.velocity_var.asDiagonal();
  Matrix9 c = covariance_;
  c.block<3, 3>(0, 0) += R_diag + delta_R_.transpose() * R_diag * delta_R_;
  c.block<3, 3>(3, 3) += V_diag + delta_R_ * V_diag * delta_R_.transpose();
  // The velocity error it leaves inside the interval, integrated: correlated
  // over about kVibrationCorrelationS.
  constexpr double kVibrationCorrelationS = 0.02;
  c.block<3, 3>(6, 6).diagonal().array() += 2.0 * v.velocity_var.maxCoeff() * kVibrationCorrelationS * dt_;
  return c;
}

Eigen::Matrix<double, 6, 1> Preintegration::bias_walk_variance() const {
  Eigen::Matrix<double, 6, 1> v;
  v.head<3>().setConstant(noise_.gyro_walk_variance(dt_));
  v.tail<3>().setConstant(noise_.accel_walk_variance(dt_));
  return v;
}

ImuState Preintegration::predict(const ImuState& start, const ImuBias& bias, const Eigen::Vector3d& gravity_w) const {
  ImuState end;
  end.R_w_i = normalized(start.R_w_i * delta_R(bias));
  end.v_w = start.v_w + gravity_w * dt_ + start.R_w_i * delta_v(bias);
  end.p_w = start.p_w + start.v_w * dt_ + 0.5 * gravity_w * dt_ * dt_ + start.R_w_i * delta_p(bias);
  return end;
}

Preintegration::Vector9 Preintegration::residual(const ImuState& start, const ImuState& end, const ImuBias& bias,
                                                 const Eigen::Vector3d& gravity_w) const {
  return inertial_residual<double>(*this, start.R_w_i, start.p_w, start.v_w, end.R_w_i, end.p_w, end.v_w, bias.gyro,
                                   bias.accel, gravity_w);
}

}  // namespace orbatlas
