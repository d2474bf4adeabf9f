#pragma once
// New map points from two keyframes (ORB-SLAM's CreateNewMapPoints for one
// neighbour): keypoints without a point, under the same vocabulary node,
// matched within the epipolar band; triangulated from the two rays (or taken
// from the stereo depth when that sees the point at a wider angle), then kept
// only if in front of both cameras, within the reprojection chi2 in both, and
// at consistent scales.
#include <memory>
#include <vector>

#include "core/geometry/triangulate.h"
#include "core/map/map.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct TriangulationStats {
  int matches = 0;  // candidate pairs from the epipolar search
  int created = 0;  // new map points
};

// Adds the new points to `map` with observations in both keyframes; appends them
// to `created` (may be null).
TriangulationStats triangulate_pair(Map& map, const std::shared_ptr<KeyFrame>& kf1,
                                    const std::shared_ptr<KeyFrame>& kf2, const FrameCamera& cam,
                                    std::vector<std::shared_ptr<MapPoint>>* created);

}  // namespace orbatlas
