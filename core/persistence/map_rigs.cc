#include "core/persistence/map_rigs.h"

namespace orbatlas {

bool same_rig(const CameraRig& a, const CameraRig& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const CameraCalibration &x = a[i], &y = b[i];
    const bool same = x.model == y.model && x.width == y.width && x.height == y.height && x.fx == y.fx &&
                      x.fy == y.fy && x.cx == y.cx && x.cy == y.cy && x.distortion == y.distortion &&
                      translation_distance(x.T_b_c, y.T_b_c) < 1e-6 && rotation_distance(x.T_b_c, y.T_b_c) < 1e-6;
    if (!same) return false;
  }
  return true;
}

bool same_mapping_rig(const MapRig& a, const MapRig& b) {
  return a.inertial == b.inertial && a.monocular == b.monocular && same_rig(a.cameras, b.cameras);
}

bool may_map_into(const MapRig& session, const MapRig& map) {
  return session.inertial == map.inertial && (session.monocular || !map.monocular) &&
         same_rig(session.cameras, map.cameras);
}

bool is_single_camera(SensorType sensor) {
  return sensor == SensorType::kMonocular || sensor == SensorType::kMonocularInertial;
}

void record_map_rigs(const Atlas& atlas, const SessionInfo& session, const std::vector<FrameAnchor>& anchors,
                     std::map<MapId, MapRig>& rigs) {
  if (is_single_camera(session.sensor)) return;
  const MapRig rig{session.cameras, session.sensor == SensorType::kStereoInertial};
  for (const FrameAnchor& a : anchors)
    if (const auto map = atlas.map_holding(a.reference)) rigs.try_emplace(*map, rig);
}

}  // namespace orbatlas
