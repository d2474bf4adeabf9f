#pragma once
// ORB-SLAM3's FullInertialBA, run by a map's local mapping after the map's
// inertial initialisation and after each refinement: the global BA with
// inertial terms (global_bundle_adjustment.h, options.inertial set: every
// keyframe and map point, plus the IMU velocities and biases of the inertial
// chain, in the map's gravity, which the initialisation just aligned), written
// straight back into the map, as local BA writes (nothing else maps it
// meanwhile). Observations are kept (robust kernel); culling is local BA's.
#include <memory>

#include "core/camera/camera.h"
#include "core/map/map.h"
#include "core/optimization/global_bundle_adjustment.h"

namespace orbatlas {

// `options.inertial` must be set; not interruptible. Returns what the solve
// found (its poses, positions and IMU states are now the map's).
GlobalBundleAdjustmentResult full_inertial_bundle_adjustment(Map& map, const Camera& camera, double bf,
                                                             const GlobalBundleAdjustmentOptions& options);

}  // namespace orbatlas
