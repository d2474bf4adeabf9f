#pragma once
// Where a tracked frame was: relative to its reference keyframe, so its pose
// follows later corrections of that keyframe (resolved with Map::keyframe_pose).
// Written by tracking, stored by the persistent atlas.
#include "core/common/timestamp.h"
#include "core/geometry/pose.h"
#include "core/common/ids.h"

namespace orbatlas {

struct FrameAnchor {
  TimestampNs t_ns = 0;
  MapId map = 0;
  KeyframeId reference = 0;
  Pose3 T_ref_b;
};

}  // namespace orbatlas
