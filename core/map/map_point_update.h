#pragma once
// Derived map-point attributes that depend on the keyframes observing it
// (ORB-SLAM's UpdateNormalAndDepth and ComputeDistinctiveDescriptors), and the
// fusion of duplicate points (ORB-SLAM's MapPoint::Replace).
#include <memory>

#include "core/map/map.h"
#include "core/map/scale_pyramid.h"

namespace orbatlas {

// Mean viewing direction over the observers and the scale-invariance distance
// range from the reference keyframe's observation. No-op for a bad point or one
// without observers.
void update_normal_and_distances(MapPoint& point, const ScalePyramid& pyramid);

// The observer descriptor with the least median Hamming distance to the others.
void update_descriptor(MapPoint& point);

// Both of the above.
void update_map_point(MapPoint& point, const ScalePyramid& pyramid);

// Moves every observation of `replaced` to `kept` (a keyframe that already sees
// `kept` just drops its slot of `replaced`), adds the tracking statistics, and
// culls `replaced` from `map`. No-op when they are the same point or either is bad.
// Returns true when `replaced` was culled.
bool replace_map_point(Map& map, const std::shared_ptr<MapPoint>& replaced, const std::shared_ptr<MapPoint>& kept);

// Adds the observation unless the keyframe already sees the point (in any slot)
// or the slot is taken; false when nothing was added.
bool add_observation_if_free(KeyFrame& keyframe, std::size_t slot, const std::shared_ptr<MapPoint>& point);

}  // namespace orbatlas
