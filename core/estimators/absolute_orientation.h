#pragma once
// Closed-form absolute orientation from 3D-3D correspondences: Horn, "Closed-form
// solution of absolute orientation using unit quaternions", JOSA A 4(4), 1987.
// The rotation is the eigenvector of the largest eigenvalue of Horn's symmetric
// 4x4 matrix N built from the centred cross-covariance; the scale is Horn's
// symmetric estimate sqrt(sum |r1|^2 / sum |r2|^2) (so aligning 1 onto 2 gives
// exactly the inverse), and t = c1 - s R c2. ORB-SLAM's Sim3Solver uses the same
// rotation with the asymmetric scale sum r1.(R r2) / sum |r2|^2; both are exact
// on noise-free data.
#include <Eigen/Core>
#include <optional>
#include <span>

#include "core/geometry/sim3.h"

namespace orbatlas {

// The S_1_2 minimising sum_i |p1[i] - S_1_2 * p2[i]|^2 (with Horn's symmetric
// scale; with estimate_scale = false the scale is exactly 1, the rigid case of
// stereo / RGB-D maps). Needs n >= 3 pairs (throws Error on fewer or on a size
// mismatch). Returns nullopt for degenerate configurations: all points of a side
// coincident, or all collinear (the rotation about that line is then undetermined,
// seen as a repeated largest eigenvalue of N).
std::optional<Sim3> horn_absolute_orientation(std::span<const Eigen::Vector3d> p1, std::span<const Eigen::Vector3d> p2,
                                              bool estimate_scale);

}  // namespace orbatlas
