#pragma once
// An atlas: several maps, one of them active, with the id allocator and object
// counters they share. No process-wide state: atlases are independent.
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/map/frame_anchor.h"
#include "core/map/id_allocator.h"
#include "core/map/keyframe_index.h"
#include "core/map/map.h"
#include "core/map/object_counters.h"

namespace orbatlas {

class Atlas {
 public:
  Atlas();
  Atlas(const Atlas&) = delete;
  Atlas& operator=(const Atlas&) = delete;

  // A new empty map with a fresh id; it becomes the active map (as in ORB-SLAM3).
  std::shared_ptr<Map> create_map();
  // A new empty map with a given id (loading a stored atlas). The allocator moves
  // above the id, so create_map never hands it out again. Throws when the atlas
  // already has a map with that id. Does not change the active map.
  std::shared_ptr<Map> add_map(MapId id);
  void set_active(MapId id);  // throws if the atlas has no such map
  std::shared_ptr<Map> active_map() const;  // null before the first create_map
  std::shared_ptr<Map> map(MapId id) const;  // null if absent
  std::vector<std::shared_ptr<Map>> maps() const;  // by id
  // A tracked frame's body pose now: its reference keyframe's current pose (it
  // follows corrections; culled references resolve through their parents)
  // times the stored offset. Null when the map or keyframe is unknown.
  std::optional<Pose3> frame_pose(const FrameAnchor& anchor) const;

  IdAllocator& ids() { return *ids_; }
  const IdAllocator& ids() const { return *ids_; }  // for peek() (saving an atlas)
  const std::shared_ptr<ObjectCounters>& counters() const { return counters_; }

  // The place-recognition index over the keyframes of every map (thread-safe):
  // local mapping adds processed keyframes and erases culled ones; relocalisation,
  // loop closing and map merging query it; loading an atlas rebuilds it.
  KeyframeIndex& keyframe_index() { return index_; }
  const KeyframeIndex& keyframe_index() const { return index_; }
  // Indexes every live keyframe of every map (after loading a stored atlas);
  // keyframes without a bag of words are skipped. Returns how many are indexed.
  std::size_t index_all_keyframes();

 private:
  const std::shared_ptr<IdAllocator> ids_;
  const std::shared_ptr<ObjectCounters> counters_;
  mutable std::mutex mutex_;  // guards maps_ and active_; no other lock is taken under it
  std::map<MapId, std::shared_ptr<Map>> maps_;
  std::shared_ptr<Map> active_;
  KeyframeIndex index_;  // has its own lock
};

}  // namespace orbatlas
