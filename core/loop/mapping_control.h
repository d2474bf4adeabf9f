#pragma once
// What loop closing needs from local mapping, which belongs to the maps (one
// mapper per map being mapped, core/slam/mapping_workers.h): stopping a map's
// mapping while the map is moved, and handing a merged map's mapping over to
// the map it joined.
#include "core/common/ids.h"

namespace orbatlas {

class MappingControl {
 public:
  virtual ~MappingControl() = default;
  // Returns once the map's local mapping has processed what was handed in and
  // waits; tracking makes no keyframe in the map until resume(). A map nobody
  // maps yet stays paused in the same way.
  virtual void pause(MapId map) = 0;
  virtual void resume(MapId map) = 0;
  // `source` was merged into `target` (both paused by the caller): keyframes
  // of the joined map go to `target`'s mapping from now on.
  virtual void merged(MapId source, MapId target) = 0;
};

}  // namespace orbatlas
