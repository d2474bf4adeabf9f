#pragma once
// Where a tracked frame was: relative to its reference keyframe, so its pose
// follows later corrections of that keyframe (resolved with
// Atlas::locate_frame). The translation is divided by the keyframe's units
// when the anchor is made (KeyFrame::units: 1 in metric maps), so it follows
// later changes of the map's scale too. Written by tracking, stored by the
// persistent atlas.
#include "core/common/timestamp.h"
#include "core/geometry/pose.h"
#include "core/common/ids.h"

namespace orbatlas {

struct FrameAnchor {
  TimestampNs t_ns = 0;
  MapId map = 0;
  KeyframeId reference = 0;
  Pose3 T_ref_b;  // its translation in the reference keyframe's units
};

}  // namespace orbatlas
