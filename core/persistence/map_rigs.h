#pragma once
// The camera rig each stored map was made with. Local mapping adjusts every
// keyframe of the map it works in with its own session's camera, so a session
// may map in (start in, relocalise into, merge into) only maps of its own rig;
// a single camera that only localises may read any map.
#include <map>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/map/atlas.h"
#include "core/map/frame_anchor.h"
#include "core/persistence/session_info.h"

namespace orbatlas {

using CameraRig = std::vector<CameraCalibration>;

// Same cameras in the same order: model, size, intrinsics, distortion, pose in the body.
bool same_rig(const CameraRig& a, const CameraRig& b);

// A single camera (mono, mono_inertial): it only localises, it makes no map.
bool is_single_camera(SensorType sensor);

// Records `session`'s rig for the maps of `atlas` holding its frames (a map
// keeps the first rig recorded); a single camera's session records nothing.
void record_map_rigs(const Atlas& atlas, const SessionInfo& session, const std::vector<FrameAnchor>& anchors,
                     std::map<MapId, CameraRig>& rigs);

}  // namespace orbatlas
