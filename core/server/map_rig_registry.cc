#include "core/server/map_rig_registry.h"

namespace orbatlas {

void MapRigRegistry::record(MapId map, const MapRig& rig) {
  std::lock_guard lock(mutex_);
  rigs_.try_emplace(map, rig);
}

void MapRigRegistry::record_session(const Atlas& atlas, const SessionInfo& session,
                                    const std::vector<FrameAnchor>& anchors) {
  std::map<MapId, MapRig> found;
  record_map_rigs(atlas, session, anchors, found);  // outside the lock: it reads the atlas
  std::lock_guard lock(mutex_);
  for (auto& [map, rig] : found) rigs_.try_emplace(map, std::move(rig));
}

void MapRigRegistry::forget(MapId map) {
  std::lock_guard lock(mutex_);
  rigs_.erase(map);
}

bool MapRigRegistry::known(MapId map) const {
  std::lock_guard lock(mutex_);
  return rigs_.count(map) > 0;
}

std::optional<MapRig> MapRigRegistry::rig_of(MapId map) const {
  std::lock_guard lock(mutex_);
  const auto it = rigs_.find(map);
  if (it == rigs_.end()) return std::nullopt;
  return it->second;
}

bool MapRigRegistry::may_merge(MapId source, MapId target) const {
  // Maps of single-camera sessions have a rig only in the server run that
  // made them (record_map_rigs).
  std::lock_guard lock(mutex_);
  const auto a = rigs_.find(source);
  const auto b = rigs_.find(target);
  return a != rigs_.end() && b != rigs_.end() && (a->second.monocular || !b->second.monocular) &&
         same_rig(a->second.cameras, b->second.cameras);
}

bool MapRigRegistry::cameras_match(const CameraRig& cameras, MapId target) const {
  std::lock_guard lock(mutex_);
  const auto b = rigs_.find(target);
  return b != rigs_.end() && same_rig(cameras, b->second.cameras);
}

bool MapRigRegistry::may_map(const MapRig& rig, MapId target) const {
  std::lock_guard lock(mutex_);
  const auto b = rigs_.find(target);
  return b != rigs_.end() && may_map_into(rig, b->second);
}

}  // namespace orbatlas
