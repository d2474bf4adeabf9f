#pragma once
// IMU preintegration on the manifold (Forster et al., "On-manifold
// preintegration for real-time visual-inertial odometry"; ORB-SLAM3's
// IMU::Preintegrated): the rotation, velocity and position increments between
// two frames or keyframes, in the IMU frame of the first, integrated once for a
// bias estimate; their covariance from the noise densities; and first-order
// Jacobians with respect to the biases and to a correction of the scale factors
// (ImuScaleCorrection, zero where integrated), so that a changed bias or scale
// corrects the increments without integrating again.
//
// Conventions: measurements and increments are in the IMU frame; a state is the
// IMU's pose and velocity in the world, whose gravity is `gravity_w` (-9.81 z
// for a gravity-aligned map). Error-state order: rotation, velocity, position.
#include <Eigen/Core>
#include <vector>

#include "core/common/timestamp.h"
#include "core/imu/imu_noise.h"
#include "core/io/euroc_types.h"

namespace orbatlas {

// The IMU's state in the world (not the body's: T_w_i = T_w_b * T_b_i).
struct ImuState {
  Eigen::Matrix3d R_w_i = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();
};

class Preintegration {
 public:
  struct Measurement {
    Eigen::Vector3d gyro, accel;  // held over dt
    double dt = 0.0;
  };
  using Matrix9 = Eigen::Matrix<double, 9, 9>;
  using Vector9 = Eigen::Matrix<double, 9, 1>;

  Preintegration(const ImuBias& bias, const ImuNoise& noise);

  // The samples between t0 and t1 (t0 < t1), each interval between two
  // consecutive samples held at the mean of its ends, the ends interpolated at
  // t0 and t1 (ORB-SLAM3 does the same); the newest sample holds until t1 when
  // it is at most `max_gap_s` before it (a live stream's next batch is on its
  // way). Throws DataError when the samples do not cover [t0, t1] so, or leave
  // a gap longer than `max_gap_s` inside it.
  static Preintegration between(const std::vector<ImuSample>& samples, TimestampNs t0, TimestampNs t1,
                                const ImuBias& bias, const ImuNoise& noise, double max_gap_s = 0.05);

  // One measurement (angular rate, specific force) held over dt > 0 seconds.
  void integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt);
  // Integrates every measurement again with a new bias (after a large change;
  // the first-order correction is good for small ones).
  void reintegrate(const ImuBias& bias);
  // `next` follows this one in time (its first measurement after this one's
  // last): this one then spans both (keyframe culling joins the increments).
  void append(const Preintegration& next);

  double dt() const { return dt_; }
  const ImuNoise& noise() const { return noise_; }
  const ImuBias& bias() const { return bias_; }  // the linearisation point
  const std::vector<Measurement>& measurements() const { return measurements_; }

  // The increments at the linearisation bias, and corrected to `bias` to first order.
  const Eigen::Matrix3d& delta_R() const { return delta_R_; }
  const Eigen::Vector3d& delta_v() const { return delta_v_; }
  const Eigen::Vector3d& delta_p() const { return delta_p_; }
  Eigen::Matrix3d delta_R(const ImuBias& bias, const ImuScaleCorrection& scale = {}) const;
  Eigen::Vector3d delta_v(const ImuBias& bias, const ImuScaleCorrection& scale = {}) const;
  Eigen::Vector3d delta_p(const ImuBias& bias, const ImuScaleCorrection& scale = {}) const;

  // Covariance of the increments' error (rotation, velocity, position): the
  // white noise's, propagated over the measurements, and the vibration's at
  // both ends (noise().vibration; its position part grows with dt()).
  Matrix9 covariance() const;
  // The white noise's part alone.
  const Matrix9& white_covariance() const { return covariance_; }
  // Covariance of the biases' drift over dt() (gyro, accel; diagonal).
  Eigen::Matrix<double, 6, 1> bias_walk_variance() const;

  // Bias Jacobians of the increments.
  const Eigen::Matrix3d& dR_dbg() const { return dR_dbg_; }
  const Eigen::Matrix3d& dv_dbg() const { return dv_dbg_; }
  const Eigen::Matrix3d& dv_dba() const { return dv_dba_; }
  const Eigen::Matrix3d& dp_dbg() const { return dp_dbg_; }
  const Eigen::Matrix3d& dp_dba() const { return dp_dba_; }
  // Scale-correction Jacobians of the increments (the rotation's is the
  // gyroscope's alone, the velocity's and position's both sensors').
  const Eigen::Matrix3d& dR_dsg() const { return dR_dsg_; }
  const Eigen::Matrix3d& dv_dsg() const { return dv_dsg_; }
  const Eigen::Matrix3d& dv_dsa() const { return dv_dsa_; }
  const Eigen::Matrix3d& dp_dsg() const { return dp_dsg_; }
  const Eigen::Matrix3d& dp_dsa() const { return dp_dsa_; }

  // The state at the end, from the state at the start, gravity and `bias`.
  ImuState predict(const ImuState& start, const ImuBias& bias, const Eigen::Vector3d& gravity_w) const;
  // The inertial residual of two states (rotation, velocity, position; zero
  // when they agree with the increments corrected to `bias`).
  Vector9 residual(const ImuState& start, const ImuState& end, const ImuBias& bias,
                   const Eigen::Vector3d& gravity_w) const;

 private:
  void reset(const ImuBias& bias);
  void propagate(const Measurement& m);

  ImuNoise noise_;
  ImuBias bias_;
  std::vector<Measurement> measurements_;
  double dt_ = 0.0;
  Eigen::Matrix3d delta_R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d delta_v_ = Eigen::Vector3d::Zero(), delta_p_ = Eigen::Vector3d::Zero();
  Matrix9 covariance_ = Matrix9::Zero();
  Eigen::Matrix3d dR_dbg_ = Eigen::Matrix3d::Zero(), dv_dbg_ = Eigen::Matrix3d::Zero(),
                  dv_dba_ = Eigen::Matrix3d::Zero(), dp_dbg_ = Eigen::Matrix3d::Zero(),
                  dp_dba_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dR_dsg_ = Eigen::Matrix3d::Zero(), dv_dsg_ = Eigen::Matrix3d::Zero(),
                  dv_dsa_ = Eigen::Matrix3d::Zero(), dp_dsg_ = Eigen::Matrix3d::Zero(),
                  dp_dsa_ = Eigen::Matrix3d::Zero();
};

// Right Jacobian of SO(3) at the rotation vector w.
Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& w);

}  // namespace orbatlas
