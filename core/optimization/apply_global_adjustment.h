#pragma once
// Bringing a finished global bundle adjustment into the map (ORB-SLAM's
// RunGlobalBundleAdjustment tail; also local mapping's full visual-inertial BA),
// with local mapping paused or by local mapping itself: keyframes and
// points the solve covered take its result; keyframes made meanwhile follow their
// spanning-tree parent's correction, points made meanwhile their reference
// keyframe's.
#include "core/map/map.h"
#include "core/map/scale_pyramid.h"
#include "core/optimization/global_bundle_adjustment.h"

namespace orbatlas {

struct GlobalAdjustmentApplyStats {
  std::size_t keyframes_set = 0, keyframes_propagated = 0;
  std::size_t points_set = 0, points_propagated = 0;
  std::size_t imu_states_set = 0;  // keyframes of the inertial chain given their optimised velocity and biases
  bool stale = false;              // the map changed its frame since the solve (Map::change_frame): nothing applied
};

GlobalAdjustmentApplyStats apply_global_adjustment(Map& map, const GlobalBundleAdjustmentResult& result,
                                                   const ScalePyramid& pyramid);

}  // namespace orbatlas
