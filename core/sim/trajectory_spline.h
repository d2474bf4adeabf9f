#pragma once
// A smooth, twice-differentiable body trajectory fitted to a sampled ground truth:
// a uniform cumulative cubic B-spline on R^3 x SO(3). The simulator renders images
// from it and synthesises the IMU from its analytic derivatives, so images, IMU
// and the ground truth it writes are exactly consistent with each other.
#include <Eigen/Core>
#include <vector>

#include "core/common/timestamp.h"
#include "core/geometry/trajectory.h"

namespace orbatlas::sim {

struct SplineState {
  Pose3 T_w_b;
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();      // velocity, world frame
  Eigen::Vector3d a_w = Eigen::Vector3d::Zero();      // acceleration, world frame
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  // angular rate, body frame
};

struct SplineOptions {
  double knot_spacing_s = 0.05;
  // Gaussian smoothing of the samples before they become control points: removes
  // the measurement noise of the real ground truth, which a second derivative
  // would amplify into unrealistic accelerations.
  double smoothing_sigma_s = 0.03;

  // Throws Error naming the first value out of range.
  void check() const;
};

class TrajectorySpline {
 public:
  // `samples`: strictly increasing, gaps of at most 0.1 s. Throws Error otherwise.
  TrajectorySpline(const Trajectory& samples, const SplineOptions& options = {});

  TimestampNs start_ns() const { return start_ns_; }
  TimestampNs end_ns() const { return end_ns_; }
  bool covers(TimestampNs t) const { return t >= start_ns_ && t <= end_ns_; }

  // State at t (must be covered; throws Error otherwise).
  SplineState evaluate(TimestampNs t) const;
  Pose3 pose(TimestampNs t) const { return evaluate(t).T_w_b; }

 private:
  TimestampNs first_knot_ns_ = 0;  // time of control point 1
  TimestampNs spacing_ns_ = 0;
  TimestampNs start_ns_ = 0, end_ns_ = 0;
  std::vector<Eigen::Vector3d> positions_;
  std::vector<Eigen::Quaterniond> rotations_;
  std::vector<Eigen::Vector3d> rotation_deltas_;  // log(R_{k-1}^T R_k), index k
};

}  // namespace orbatlas::sim
