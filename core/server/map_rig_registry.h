#pragma once
// The camera rig each map of the atlas was made with (map_rigs.h), as the
// server learns it: from the stored sessions at start, from a live session's
// first frame in a map, from other replicas' sessions; dropped when a map is
// merged away. Answers which maps may be merged, localised in or mapped by a
// rig. Thread-safe; its mutex is a leaf (the merging worker asks under the
// keyframe index's lock).
#include <map>
#include <mutex>
#include <optional>
#include <vector>

#include "core/common/ids.h"
#include "core/map/atlas.h"
#include "core/persistence/map_rigs.h"

namespace orbatlas {

class MapRigRegistry {
 public:
  // `map` was made with `rig` (a map keeps the first rig recorded).
  void record(MapId map, const MapRig& rig);
  // The rigs of the maps holding a stored session's frames (record_map_rigs).
  void record_session(const Atlas& atlas, const SessionInfo& session, const std::vector<FrameAnchor>& anchors);
  void forget(MapId map);  // merged away
  bool known(MapId map) const;
  std::optional<MapRig> rig_of(MapId map) const;

  // May `source` be merged into `target`? Both known, the same cameras, and a
  // single camera's map goes into a stereo one of its rig, not the reverse.
  bool may_merge(MapId source, MapId target) const;
  // Was `target` made with these cameras (localisation reads any such map)?
  bool cameras_match(const CameraRig& cameras, MapId target) const;
  // May a session of `rig` map in `target` (may_map_into)?
  bool may_map(const MapRig& rig, MapId target) const;

 private:
  mutable std::mutex mutex_;  // a leaf
  std::map<MapId, MapRig> rigs_;
};

}  // namespace orbatlas
