#pragma once
// Ceres costs of visual-inertial optimisation (ORB-SLAM3's EdgeInertial and the
// prior of a frame's state), on the parameter blocks the visual costs use: a
// camera pose T_c_w as PoseParameters (quaternion x y z w on
// ceres::EigenQuaternionManifold, translation), the IMU's velocity in the world
// (3), and the IMU biases (gyro, accelerometer: 6).
#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <memory>

#include "core/geometry/pose.h"
#include "core/imu/preintegration.h"

namespace orbatlas {

// The inertial residual of two states (Preintegration::residual: rotation,
// velocity, position), weighted by the square root of the increments'
// information, so that its squared norm is a chi2 with 9 degrees of freedom.
// Parameter blocks, in order: q_c_w and t_c_w of the first frame, its IMU
// velocity, the same three of the second frame, the biases the increments are
// corrected to (first order, Preintegration::delta_*(bias)). T_c_i: the IMU in
// the camera (p_c = T_c_i * p_i); gravity_w: gravity in the world.
std::unique_ptr<ceres::CostFunction> make_inertial_cost(std::shared_ptr<const Preintegration> increments,
                                                        const Pose3& T_c_i, const Eigen::Vector3d& gravity_w);

// The same with an eighth parameter block: the correction of the IMU's scale
// factors (ImuScaleCorrection: gyro, accel; 6) the increments are corrected to
// (first order), shared by the terms of one IMU.
std::unique_ptr<ceres::CostFunction> make_scaled_inertial_cost(std::shared_ptr<const Preintegration> increments,
                                                               const Pose3& T_c_i, const Eigen::Vector3d& gravity_w);

// A Gaussian prior on a frame's state: the camera pose and the IMU velocity,
// with `covariance` in the tangent coordinates Ceres' quaternion manifold and
// the translation and velocity blocks use (a left rotation increment of q_c_w,
// then t_c_w, then v_w). Parameter blocks: q_c_w, t_c_w, v_w.
using StateCovariance = Eigen::Matrix<double, 9, 9>;
std::unique_ptr<ceres::CostFunction> make_state_prior(const Pose3& T_c_w, const Eigen::Vector3d& v_w,
                                                      const StateCovariance& covariance);

// The biases' random walk between two keyframes dt seconds apart (ORB-SLAM3's
// EdgeGyroRW and EdgeAccRW): (b2 - b1) over the walk's sigma over dt, per
// component. Parameter blocks: the biases (gyro, accelerometer: 6) of the
// first keyframe, then of the second.
std::unique_ptr<ceres::CostFunction> make_bias_walk_cost(const ImuNoise& noise, double dt);

// ||A (x - mean)|| for a block of `mean.size()` values with independent sigmas.
std::unique_ptr<ceres::CostFunction> make_diagonal_prior(const Eigen::VectorXd& mean, const Eigen::VectorXd& sigma);

}  // namespace orbatlas
