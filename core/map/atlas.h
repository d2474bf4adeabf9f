#pragma once
// An atlas: several maps, one of them active, with the id allocator and object
// counters they share. No process-wide state: atlases are independent.
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <vector>

#include "core/common/writer_priority_mutex.h"
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
  void set_active(MapId id);                       // throws if the atlas has no such map
  std::shared_ptr<Map> active_map() const;         // null before the first create_map
  std::shared_ptr<Map> map(MapId id) const;        // null if absent
  std::vector<std::shared_ptr<Map>> maps() const;  // by id
  // Takes a map out of the atlas (after a merge emptied it); null if absent.
  // The active map becomes none when it was this one.
  std::shared_ptr<Map> remove_map(MapId id);
  // Every map removed so far (a full save deletes their stored rows).
  std::vector<MapId> removed_maps() const;
  // A new empty map with a given id that is not (yet) in the atlas: a newer
  // copy of a map read from the database, for replace_map. The allocator is
  // not moved (the id is another writer's, or already known).
  std::shared_ptr<Map> detached_map(MapId id) const;
  // Puts `map` in the atlas in place of the map with its id (or as a new one),
  // not recording the old one as removed: it is the same map, read again.
  // Returns the old one (null if none). Hold lock_maps_exclusive().
  std::shared_ptr<Map> replace_map(std::shared_ptr<Map> map);
  // The map now holding a keyframe id, alive or culled (merges move keyframes
  // between maps); none when no map knows it.
  std::optional<MapId> map_holding(KeyframeId keyframe) const;
  // A tracked frame's body pose now: its reference keyframe's current pose (it
  // follows corrections; culled references resolve through their parents)
  // times the stored offset. When a merge moved the reference into another
  // map, the pose is in that map's world (see map_holding). Null when no map
  // knows the keyframe.
  std::optional<Pose3> frame_pose(const FrameAnchor& anchor) const;
  // The same with the map the frame is in now.
  std::optional<std::pair<MapId, Pose3>> locate_frame(const FrameAnchor& anchor) const;

  // Edits that move whole maps or many of their objects at once (a merge, a loop
  // correction, applying a global BA) hold this exclusively; readers that must
  // see every map whole (a checkpoint collecting rows, a localisation request, a
  // localisation session's frame) hold it shared: they see a map before or after
  // such an edit, never half-way. A waiting edit goes before new readers
  // (WriterPriorityMutex), so a stream of frames cannot hold it off. Taken before
  // any map's or object's lock; never twice by one thread.
  // Each exclusive hold counts as one whole-map edit (maps_edits): a frame
  // tracked after one may have moved with the correction (the live pose's jump).
  std::unique_lock<WriterPriorityMutex> lock_maps_exclusive() {
    std::unique_lock lock(maps_edit_mutex_);
    maps_edits_.fetch_add(1, std::memory_order_relaxed);
    return lock;
  }
  std::shared_lock<WriterPriorityMutex> lock_maps_shared() const { return std::shared_lock(maps_edit_mutex_); }
  // As lock_maps_shared(), giving up at `deadline` (the lock does not own it then).
  std::shared_lock<WriterPriorityMutex> lock_maps_shared_until(std::chrono::steady_clock::time_point deadline) const {
    return std::shared_lock(maps_edit_mutex_, deadline);
  }
  // Whole-map edits so far (merges, loop corrections, global BA results, inertial
  // initialisations applied); read under lock_maps_shared() it is stable.
  std::uint64_t maps_edits() const { return maps_edits_.load(std::memory_order_relaxed); }

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
  mutable WriterPriorityMutex maps_edit_mutex_;
  std::atomic<std::uint64_t> maps_edits_{0};
  mutable std::mutex mutex_;  // guards maps_ and active_; no other lock is taken under it
  std::map<MapId, std::shared_ptr<Map>> maps_;
  std::vector<MapId> removed_;
  std::shared_ptr<Map> active_;
  KeyframeIndex index_;  // has its own lock
};

}  // namespace orbatlas
