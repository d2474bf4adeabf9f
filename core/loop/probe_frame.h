#pragma once
// A keyframe seen as a tracking Frame (its features, stereo, grid and bag of
// words, its pose, no associations yet), so that place recognition can reuse
// tracking's searches (search_by_bow, search_projected_points) to associate a
// keyframe's keypoints with the map points of another part of the map.
#include "core/map/keyframe.h"
#include "core/tracking/frame.h"

namespace orbatlas {

Frame probe_frame(const KeyFrame& keyframe);

// Keyframe slots that the probe associated (map_points non-null, not outliers).
int associated_count(const Frame& probe);

}  // namespace orbatlas
