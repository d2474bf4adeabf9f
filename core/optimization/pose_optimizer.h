#pragma once
// Motion-only optimisation of one frame's camera pose from 2D-3D (and rectified
// stereo) correspondences: ORB-SLAM's PoseOptimization. Rounds of a few
// Levenberg-Marquardt iterations with a Huber kernel; after each round every
// correspondence is classified by its chi2 (outliers are left out of the next
// round, inliers — including earlier outliers that now fit — are kept). See
// docs/optimization.md.
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "core/camera/camera.h"
#include "core/geometry/pose.h"
#include "core/imu/imu_noise.h"
#include "core/optimization/chi2.h"
#include "core/optimization/inertial_cost.h"

namespace orbatlas {

struct PoseCorrespondence {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();  // map point in the world
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();   // observed keypoint (the camera model's image)
  std::optional<double> u_right;                  // rectified stereo: right-image column
  double level_sigma2 = 1.0;                      // sigma^2 of the keypoint's pyramid level
};

// A visual-inertial frame (ORB-SLAM3's PoseInertialOptimizationLastFrame): the
// IMU increments from the previous frame tie this frame's pose and IMU velocity
// to the previous frame's state, which is optimised too under a Gaussian prior
// (what the previous frame's own optimisation left: its marginal covariance),
// and the biases, under a prior at the map's estimate.
struct InertialPoseTerm {
  std::shared_ptr<const Preintegration> increments;  // previous frame -> this frame
  Pose3 T_c_i;                                       // the IMU in the camera
  Eigen::Vector3d gravity_w = Eigen::Vector3d::Zero();
  Pose3 previous_T_c_w;
  Eigen::Vector3d previous_v_w = Eigen::Vector3d::Zero();
  StateCovariance previous_covariance = StateCovariance::Identity();  // tangent coordinates (inertial_cost.h)
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();                      // this frame's velocity: the start
  ImuBias bias;                                                       // the prior's mean
  Eigen::Matrix<double, 6, 1> bias_sigma = Eigen::Matrix<double, 6, 1>::Ones();  // gyro, accel
};

struct InertialPoseEstimate {
  Eigen::Vector3d v_w = Eigen::Vector3d::Zero();  // this frame's IMU velocity
  ImuBias bias;
  // Of this frame's pose and velocity (the next frame's prior); none when
  // Ceres could not compute it (a degenerate problem).
  std::optional<StateCovariance> covariance;
  double chi2 = 0.0;  // of the inertial residual at the end
};

struct PoseOptimizerInput {
  Pose3 T_c_w;  // initial camera pose (world -> camera)
  std::vector<PoseCorrespondence> correspondences;
  double bf = 0.0;  // stereo baseline * fx; needed when a correspondence has u_right
  std::optional<InertialPoseTerm> inertial;
};

struct PoseOptimizerOptions {
  int rounds = 4;
  int iterations_per_round = 10;
  int robust_rounds = 3;  // the Huber kernel is used in the first rounds only (ORB-SLAM: 3 of 4)
  double chi2_mono = kChi2Mono95;
  double chi2_stereo = kChi2Stereo95;
  double huber_mono = std::sqrt(kChi2Mono95);
  double huber_stereo = std::sqrt(kChi2Stereo95);
  int min_correspondences = 3;  // fewer: the pose is returned unchanged, no inliers
  int min_round_inliers = 10;   // stop the rounds when fewer inliers remain

  // Throws Error naming the first value out of range.
  void check() const;
};

struct PoseOptimizerResult {
  Pose3 T_c_w;
  std::vector<std::uint8_t> inliers;  // per correspondence: 1 inlier, 0 outlier
  int inlier_count = 0;
  int rounds = 0;                                // rounds run
  int iterations = 0;                            // Levenberg-Marquardt iterations, all rounds
  std::optional<InertialPoseEstimate> inertial;  // with an inertial term
};

// Throws Error when a stereo correspondence comes without bf > 0 or a sigma2 is
// not positive. `camera` is the model the keypoints were observed with.
PoseOptimizerResult optimize_pose(const Camera& camera, const PoseOptimizerInput& input,
                                  const PoseOptimizerOptions& options = {});

}  // namespace orbatlas
