#include "core/tracking/inertial_tracking.h"

#include <cmath>

#include "core/common/error.h"
#include "core/tracking/frame_pose.h"

namespace orbatlas {

void InertialTrackingOptions::check() const {
  ORBATLAS_CHECK(std::isfinite(max_imu_only_s) && max_imu_only_s >= 0.0,
                 "inertial tracking: max_imu_only_s must be >= 0, not " << max_imu_only_s);
  ORBATLAS_CHECK(loose_rotation_sigma > 0.0 && loose_position_sigma > 0.0 && loose_velocity_sigma > 0.0,
                 "inertial tracking: the loose prior's sigmas must be > 0");
  ORBATLAS_CHECK(bias_prior_window_s > 0.0,
                 "inertial tracking: bias_prior_window_s must be > 0, not " << bias_prior_window_s);
}

InertialTracking::InertialTracking(const ImuBuffer& imu, const ImuNoise& noise, const Pose3& T_b_i, const Pose3& T_b_c,
                                   InertialTrackingOptions options)
    : imu_(imu), noise_(noise), T_b_i_(T_b_i), T_b_c_(T_b_c), T_c_i_(T_b_c.inverse() * T_b_i), options_(options) {
  noise_.check();
  options_.check();
}

ImuState InertialTracking::imu_state(const Pose3& T_w_b, const Eigen::Vector3d& v_w) const {
  const Pose3 T_w_i = T_w_b * T_b_i_;
  ImuState s;
  s.R_w_i = T_w_i.q.normalized().toRotationMatrix();
  s.p_w = T_w_i.t;
  s.v_w = v_w;
  return s;
}

StateCovariance InertialTracking::loose_covariance(double bridged_s) const {
  StateCovariance c = StateCovariance::Zero();
  // The position also drifts by the velocity's error over the time the IMU alone carried it.
  const double position_sigma = std::hypot(options_.loose_position_sigma, options_.loose_velocity_sigma * bridged_s);
  c.diagonal().segment<3>(0).setConstant(options_.loose_rotation_sigma * options_.loose_rotation_sigma);
  c.diagonal().segment<3>(3).setConstant(position_sigma * position_sigma);
  c.diagonal().segment<3>(6).setConstant(options_.loose_velocity_sigma * options_.loose_velocity_sigma);
  return c;
}

namespace {

// The state covariance (inertial_cost.h's coordinates: rotation and
// translation of T_c_w, then v_w) with its velocity block turned by R: v' = R v.
StateCovariance turn_velocity_block(const StateCovariance& c, const Eigen::Matrix3d& R) {
  StateCovariance J = StateCovariance::Identity();
  J.block<3, 3>(6, 6) = R;
  return J * c * J.transpose();
}

}  // namespace

std::optional<Pose3> InertialTracking::predict(const Map& map, const Frame& last, TimestampNs t_ns,
                                               const std::optional<ImuBias>& own_bias) {
  prediction_.reset();
  if (!last_ || !last.has_pose || last.t_ns != last_->t_ns || t_ns <= last.t_ns) return std::nullopt;
  auto state = map.inertial_state();
  if (!state) return std::nullopt;
  if (own_bias) state->bias = *own_bias;
  // Empty when the IMU does not cover the interval: visual tracking only.
  std::optional<Preintegration> increments = imu_.between(last.t_ns, t_ns, state->bias, noise_);
  if (!increments) return std::nullopt;
  Prediction p;
  p.t_ns = t_ns;
  p.map = *state;
  p.last_T_w_b = last.T_w_b;
  const ImuState start = imu_state(last.T_w_b, Eigen::Vector3d::Zero());
  p.last_v_w = start.R_w_i * last_->v_i;
  p.increments = std::make_shared<const Preintegration>(std::move(*increments));
  p.predicted = p.increments->predict(imu_state(last.T_w_b, p.last_v_w), state->bias, state->gravity_w);
  const Pose3 T_w_i(Eigen::Quaterniond(p.predicted.R_w_i), p.predicted.p_w);
  const Pose3 T_w_b = T_w_i * T_b_i_.inverse();
  prediction_ = std::move(p);
  return T_w_b;
}

std::optional<int> InertialTracking::optimize(Frame& frame, const FrameCamera& cam,
                                              const PoseOptimizerOptions& options) {
  if (!prediction_ || prediction_->t_ns != frame.t_ns) return std::nullopt;
  Prediction& p = *prediction_;
  InertialPoseTerm term;
  term.increments = p.increments;
  term.T_c_i = T_c_i_;
  term.gravity_w = p.map.gravity_w;
  term.previous_T_c_w = (p.last_T_w_b * T_b_c_).inverse();
  term.previous_v_w = p.last_v_w;
  const double bridged_s =
      last_visual_ns_ > 0 && last_->t_ns > last_visual_ns_ ? ns_to_s(last_->t_ns - last_visual_ns_) : 0.0;
  // Kept with the velocity in the last frame's IMU frame: back to the world it is in now.
  term.previous_covariance =
      last_->covariance
          ? turn_velocity_block(*last_->covariance, imu_state(p.last_T_w_b, Eigen::Vector3d::Zero()).R_w_i)
          : loose_covariance(bridged_s);
  term.v_w = p.predicted.v_w;
  term.bias = p.map.bias;
  const double window = options_.bias_prior_window_s;
  term.bias_sigma.head<3>().setConstant(std::sqrt(noise_.gyro_walk_variance(window)));
  term.bias_sigma.tail<3>().setConstant(std::sqrt(noise_.accel_walk_variance(window)));
  const int inliers = optimize_frame_pose(frame, cam, T_b_c_, options, term, p.estimate);
  if (p.estimate) ++optimized_frames_;
  return inliers;
}

std::optional<InertialTracking::FrameImuState> InertialTracking::frame_state(TimestampNs t_ns) const {
  if (!prediction_ || prediction_->t_ns != t_ns) return std::nullopt;
  if (prediction_->estimate) return FrameImuState{prediction_->estimate->v_w, prediction_->estimate->bias};
  return FrameImuState{prediction_->predicted.v_w, prediction_->map.bias};
}

bool InertialTracking::may_bridge(TimestampNs t_ns) const {
  return prediction_ && prediction_->t_ns == t_ns && ns_to_s(t_ns - last_visual_ns_) <= options_.max_imu_only_s;
}

void InertialTracking::frame_done(const Frame& frame, const Frame* previous, Outcome outcome) {
  std::optional<Prediction> prediction;
  if (prediction_ && prediction_->t_ns == frame.t_ns) prediction = std::move(prediction_);
  prediction_.reset();
  if (outcome == Outcome::kLost || !frame.has_pose) {
    last_.reset();
    return;
  }
  const ImuState now = imu_state(frame.T_w_b, Eigen::Vector3d::Zero());
  LastState s;
  s.t_ns = frame.t_ns;
  if (outcome == Outcome::kImuOnly) {
    if (!prediction) {  // nothing to carry the state on
      last_.reset();
      return;
    }
    s.v_i = now.R_w_i.transpose() * prediction->predicted.v_w;  // the covariance: the loose prior
  } else if (prediction && prediction->estimate) {
    s.v_i = now.R_w_i.transpose() * prediction->estimate->v_w;
    // Velocity block in the frame's IMU frame, as v_i: a move of the frame (a
    // loop's yaw, the map turned to gravity) carries it along.
    if (prediction->estimate->covariance)
      s.covariance = turn_velocity_block(*prediction->estimate->covariance, now.R_w_i.transpose());
    bias_ = prediction->estimate->bias;
    last_visual_ns_ = frame.t_ns;
  } else {
    last_visual_ns_ = frame.t_ns;
    // Tracked visually without the IMU: the velocity from the last two poses.
    if (!previous || !previous->has_pose || previous->t_ns >= frame.t_ns) {
      last_.reset();
      return;
    }
    const double dt = ns_to_s(frame.t_ns - previous->t_ns);
    const Eigen::Vector3d v_w = (now.p_w - imu_state(previous->T_w_b, Eigen::Vector3d::Zero()).p_w) / dt;
    s.v_i = now.R_w_i.transpose() * v_w;
  }
  last_ = s;
}

void InertialTracking::rescale(double factor) {
  if (!last_) return;
  last_->v_i *= factor;
  if (last_->covariance) {
    // Position and velocity sigmas scale with the units.
    StateCovariance J = StateCovariance::Identity();
    J.block<6, 6>(3, 3) *= factor;
    last_->covariance = J * *last_->covariance * J.transpose();
  }
}

std::optional<Eigen::Quaterniond> InertialTracking::level_rotation(TimestampNs t_ns) const {
  constexpr double kWindowS = 0.5, kGravity = 9.81;
  const auto f_i = imu_.mean_accel(t_ns, kWindowS, 1);
  if (!f_i || !(f_i->norm() >= 0.5 * kGravity && f_i->norm() <= 2.0 * kGravity)) return std::nullopt;
  const Eigen::Vector3d up_b = T_b_i_.q * *f_i;  // at rest the specific force points up
  return Eigen::Quaterniond::FromTwoVectors(up_b, Eigen::Vector3d::UnitZ());
}

void InertialTracking::reset() {
  last_.reset();
  prediction_.reset();
}

}  // namespace orbatlas
