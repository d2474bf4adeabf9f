#pragma once
// Fusing duplicate map points (ORB-SLAM's ORBmatcher::Fuse): each point is
// projected into a keyframe; if a keypoint there matches it (descriptor and
// reprojection chi2), the point is either added as that keypoint's observation or,
// when the keypoint already has a point, the two are merged into the one with more
// observations.
#include <memory>
#include <vector>

#include "core/map/map.h"
#include "core/tracking/frame_camera.h"

namespace orbatlas {

struct FusionStats {
  int added = 0;   // new observations of existing points
  int merged = 0;  // duplicate points replaced
};

FusionStats fuse_into_keyframe(Map& map, const std::shared_ptr<KeyFrame>& keyframe,
                               const std::vector<std::shared_ptr<MapPoint>>& points, const FrameCamera& cam,
                               float th = 3.0f);

}  // namespace orbatlas
