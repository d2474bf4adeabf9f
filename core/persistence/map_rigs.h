#pragma once
// The camera rig each stored map was made with. Local mapping adjusts every
// keyframe of the map it works in with its own session's camera, so a session
// may map in (start in, relocalise into, merge into) only maps of its own rig;
// a single camera that only localises may read any map. Whether the sessions
// that mapped it fused an IMU is recorded too: a server's mapping of a rig is
// made with one session's options, so sessions that fuse an IMU and sessions
// that do not map apart (docs/server.md).
#include <map>
#include <vector>

#include "core/camera/camera_calibration.h"
#include "core/map/atlas.h"
#include "core/map/frame_anchor.h"
#include "core/persistence/session_info.h"

namespace orbatlas {

using CameraRig = std::vector<CameraCalibration>;

struct MapRig {
  CameraRig cameras;
  bool inertial = false;   // mapped by sessions that fuse their IMU
  bool monocular = false;  // mapped by single-camera sessions (monocular SLAM)
};

// Same cameras in the same order: model, size, intrinsics, distortion, pose in the body.
bool same_rig(const CameraRig& a, const CameraRig& b);

// A single camera (mono, mono_inertial): a monocular session or a localising one.
bool is_single_camera(SensorType sensor);

// Same cameras, both with or both without the IMU fused, both monocular or
// both not: sessions that may share one local mapping.
bool same_mapping_rig(const MapRig& a, const MapRig& b);

// May a session of rig `session` map in (enter, merge into) a map made by rig
// `map`? Same cameras and IMU use, and a monocular session may also take a
// map its cameras' stereo sessions made (it then maps at that map's metric
// scale; the left camera of the rig, docs/monocular.md), not the reverse.
bool may_map_into(const MapRig& session, const MapRig& map);

// Records `session`'s rig for the maps of `atlas` holding its frames (a map
// keeps the first rig recorded; a stereo_inertial session's counts as fusing
// its IMU); a single camera's session records nothing.
void record_map_rigs(const Atlas& atlas, const SessionInfo& session, const std::vector<FrameAnchor>& anchors,
                     std::map<MapId, MapRig>& rigs);

}  // namespace orbatlas
