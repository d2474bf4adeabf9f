#pragma once
// How far a rig turned about gravity over a run of its poses: what tells a
// horizontal accelerometer bias from a tilt of gravity. A bias fixed in the IMU
// turns with the rig, a tilt of gravity does not; while the rig keeps its
// heading the two are the same measurement, and an estimate that frees the
// bias splits the two by the noise (docs/inertial.md, "Refinements").
#include <Eigen/Core>
#include <vector>

namespace orbatlas {

// The spread of the headings of `R_w_i` (the IMU's rotation in the world) about
// the direction `gravity_w`, in degrees: the largest less the smallest heading
// measured from the first rotation's, each in (-180, 180]. The heading is that
// of the IMU axis lying closest to the horizontal plane on average (a drone's x,
// a hand-held rig's whichever is level). 0 for fewer than two rotations or a
// zero gravity.
double turn_about_gravity_deg(const std::vector<Eigen::Matrix3d>& R_w_i, const Eigen::Vector3d& gravity_w);

}  // namespace orbatlas
