#pragma once
// Pose-only optimisation of a frame from its map-point associations.
#include "core/geometry/pose.h"
#include "core/optimization/pose_optimizer.h"
#include "core/tracking/projection_search.h"

namespace orbatlas {

// Optimises frame.T_w_b (the initial guess) against every associated, live map
// point; flags frame.outlier per keypoint; returns the number of inliers.
// T_b_c: the tracking camera in the body.
int optimize_frame_pose(Frame& frame, const FrameCamera& cam, const Pose3& T_b_c,
                        const PoseOptimizerOptions& options = {});
// The same with an inertial term (visual-inertial tracking); `estimate` gets
// the frame's velocity, biases and state covariance.
int optimize_frame_pose(Frame& frame, const FrameCamera& cam, const Pose3& T_b_c, const PoseOptimizerOptions& options,
                        const InertialPoseTerm& inertial, std::optional<InertialPoseEstimate>& estimate);

// Drops the outlier associations (and those to culled points); returns how many
// associations remain whose point is observed by at least one keyframe.
int discard_outliers(Frame& frame);

}  // namespace orbatlas
