#pragma once
// Applying a loop (or merge) correction expressed as similarities, as ORB-SLAM's
// LoopClosing::CorrectLoop and Optimizer::OptimizeEssentialGraph do.
//
// Conventions. A keyframe's pose before the correction is the rigid T_c_w_old
// (world -> camera, scale 1). Its corrected pose is a similarity S_c_w_new (world
// -> camera): the corrected world is mapped into the keyframe's *old* camera
// frame, including the scale change. Every map point keeps its position in the
// camera frame of its reference keyframe:
//
//     p_w_new = S_c_w_new^-1 * (T_c_w_old * p_w_old)
//
// and the keyframe's corrected rigid pose in the corrected world is
// T_c_w_new = [R, t / s] of S_c_w_new = (R, t, s): the old camera frame scaled by 1/s.
#include <Eigen/Core>

#include "core/geometry/pose.h"
#include "core/geometry/sim3.h"

namespace orbatlas {

// ORB-SLAM's "CorrectedSim3" propagation: keyframe i was connected to keyframe c
// (the one whose correction is known) by the old relative pose T_i_c =
// T_i_w_old * T_c_w_old^-1; the correction moves i rigidly with c:
// S_i_w_new = T_i_c * S_c_w_new.
Sim3 propagate_correction(const Pose3& T_i_w_old, const Pose3& T_c_w_old, const Sim3& S_c_w_new);

// A world point seen through the keyframe with old pose T_c_w_old moved to the
// corrected world: S_c_w_new^-1 * (T_c_w_old * p_w_old).
Eigen::Vector3d correct_point(const Pose3& T_c_w_old, const Sim3& S_c_w_new, const Eigen::Vector3d& p_w_old);

// The rigid pose T_c_w of a world->camera similarity: [R, t / s]. The camera's
// view of the corrected world equals its old view up to the scale 1/s.
Pose3 rigid_pose_c_w(const Sim3& S_c_w);

}  // namespace orbatlas
