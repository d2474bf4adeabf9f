#pragma once
// The inertial part of visual-inertial local bundle adjustment (ORB-SLAM3's
// LocalInertialBA, internal to orbatlas_optimization): along the inertial
// chain ending at the current keyframe, the last keyframes (the temporal
// window) get their IMU velocity and biases as unknowns, tied to their poses
// by the preintegrated IMU between consecutive keyframes (make_inertial_cost,
// at the first keyframe's biases) and to each other by the biases' random walk
// (make_bias_walk_cost). The keyframe before the window, when it has an IMU
// state, joins fixed (pose, velocity and biases): the window's anchor.
#include <cmath>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include "core/geometry/pose.h"
#include "core/imu/imu_noise.h"
#include "core/map/keyframe.h"
#include "core/optimization/bundle_problem.h"
#include "core/optimization/chi2.h"

namespace orbatlas {

struct InertialWindowOptions {
  // The IMU in the body frame, for a chain whose links do not carry the IMU
  // in the camera (InertialLink::T_c_i: links stored before schema 8).
  Pose3 T_b_i;
  Eigen::Vector3d gravity_w = Eigen::Vector3d::Zero();  // in the map
  ImuBias map_bias;                                     // for keyframes without an IMU state
  std::size_t temporal_keyframes = 10;                  // ORB-SLAM3: 10
  // A Huber kernel of this width on each link's whitened inertial residual
  // (the global BA's; 0: none): a link that does not fit (a knock, a bad
  // stretch of IMU) weighs as a robust term, not as a square.
  double huber = std::sqrt(kChi2Inertial95);
  // The IMU's scale-factor correction (ImuScaleCorrection), the map's estimate:
  // the inertial terms are corrected to it. With scale_sigma > 0 it is an
  // unknown of the window too, under a prior of that sigma per axis about the
  // map's estimate; 0: held at it.
  ImuScaleCorrection scale = {};
  double scale_sigma = 0.0;

  // Throws Error naming the first value out of range.
  void check() const;
};

struct InertialWindow {
  std::vector<std::shared_ptr<KeyFrame>> keyframes;  // oldest first; the anchor first when anchored
  std::vector<std::size_t> index;                    // into BundleProblem::keyframes
  std::vector<std::size_t> velocity, bias;           // into BundleProblem::extra_blocks
  std::vector<std::size_t> inertial_terms;           // into BundleProblem::extra_terms: the inertial edges
  std::size_t scale = 0;                             // into BundleProblem::extra_blocks (when has_scale)
  bool has_scale = false;
  bool anchored = false;
};

// The chain's keyframes to optimise with their IMU states: the temporal window
// ending at `current` (its first element the anchor when `anchored`), for the
// caller to put in the bundle problem's window (all but the anchor).
struct InertialChainWindow {
  std::vector<std::shared_ptr<KeyFrame>> keyframes;
  bool anchored = false;
};
InertialChainWindow inertial_chain_window(const std::shared_ptr<KeyFrame>& current,
                                          const InertialWindowOptions& options);

// Adds the window's velocity and bias blocks and its inertial and bias-walk
// terms to `problem` (whose window holds every keyframe of `chain` but the
// anchor; the anchor joins fixed). A keyframe without an IMU state starts from
// the velocity its neighbours' positions imply and the map's biases.
InertialWindow add_inertial_window(BundleProblem& problem, const InertialChainWindow& chain,
                                   const InertialWindowOptions& options);

// The chi2 of the window's inertial edges at the current estimates (9 degrees
// of freedom each), in order.
std::vector<double> inertial_window_chi2(const BundleProblem& problem, const InertialWindow& window);

// The free keyframes' optimised IMU states (velocity in the IMU frame of the
// optimised pose); non-finite ones are left out.
std::vector<std::pair<std::shared_ptr<KeyFrame>, KeyFrame::ImuState>> inertial_window_states(
    const BundleProblem& problem, const InertialWindow& window, const InertialWindowOptions& options);

// The window's scale-factor correction as solved (the options' when the
// window has none or it is not finite).
ImuScaleCorrection inertial_window_scale(const BundleProblem& problem, const InertialWindow& window,
                                         const InertialWindowOptions& options);

// What the window's inertial terms tell of its scale correction (6x6, gyro
// then accel): the information of the correction at the solution with the
// biases (taken as one for the window) eliminated, the poses and velocities
// taken as known; zero when the window has no scale block.
using ImuScaleInformation = Eigen::Matrix<double, 6, 6>;
ImuScaleInformation inertial_window_scale_information(const BundleProblem& problem, const InertialWindow& window);

// Writes the free keyframes' IMU states back (inertial_window_states).
void write_back_inertial_window(const BundleProblem& problem, const InertialWindow& window,
                                const InertialWindowOptions& options);

}  // namespace orbatlas
