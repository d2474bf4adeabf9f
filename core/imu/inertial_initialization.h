#pragma once
// Inertial-only maximum-a-posteriori initialisation (ORB-SLAM3, "Inertial-only
// MAP estimation", ../shared/seeds/orbslam3_paper_notes.txt): with the
// keyframe poses of the visual map held fixed, the direction of gravity, every
// keyframe's velocity and one gyro and accelerometer bias for the window (and,
// for a single camera, the map's scale) are estimated from the IMU
// preintegrated between consecutive keyframes, with a prior pulling the biases
// towards zero. Stereo maps are metric: the scale stays 1.
#include <Eigen/Core>
#include <vector>

#include "core/common/timestamp.h"
#include "core/geometry/pose.h"
#include "core/imu/imu_noise.h"
#include "core/imu/preintegration.h"

namespace orbatlas {

struct InertialInitOptions {
  double gravity = 9.81;        // m/s^2
  bool estimate_scale = false;  // monocular maps
  // Prior information of the biases (ORB-SLAM3's priorG and priorA for stereo):
  // residual sqrt(prior) * bias.
  double gyro_bias_prior = 1e2;
  double accel_bias_prior = 1e5;
  int max_iterations = 200;
  // The keyframe poses' own error (each end of a link), for the chi2 that
  // InertialInitResult reports: the residuals there are the IMU's and the
  // visual poses' disagreement.
  double visual_rotation_sigma = 5e-4;  // rad
  double visual_position_sigma = 5e-3;  // m

  // Throws Error naming the first value out of range.
  void check() const;
};

struct InertialInitResult {
  Eigen::Matrix3d R_w_g = Eigen::Matrix3d::Identity();  // gravity frame -> map frame (yaw left as it was)
  Eigen::Vector3d gravity_w = Eigen::Vector3d::Zero();  // gravity in the map frame
  std::vector<Eigen::Vector3d> velocities;              // of the IMU, map frame, one per keyframe
  ImuBias bias;
  double scale = 1.0;
  double initial_cost = 0.0, final_cost = 0.0;
  // Per link (k to k+1): the chi2 of its inertial residual (9 degrees of
  // freedom) at the solution, under the increments' covariance and the
  // keyframe poses' error (InertialInitOptions::visual_*_sigma).
  std::vector<double> link_chi2;
  // The same of the rotation residual alone (3 degrees of freedom): the gyro
  // against the visual rotation, whatever the accelerometer bias's prior holds.
  std::vector<double> link_rotation_chi2;
  int iterations = 0;
  bool converged = false;
};

// `T_w_b`: the keyframes' body poses in the map, in time order (at least 3);
// `preintegrated[k]`: the IMU between keyframe k and k+1 (n - 1 of them);
// `T_b_i`: the IMU in the body frame. Throws Error on inconsistent input.
InertialInitResult initialize_inertial(const std::vector<Pose3>& T_w_b,
                                       const std::vector<Preintegration>& preintegrated, const Pose3& T_b_i,
                                       const InertialInitOptions& options = {});

}  // namespace orbatlas
