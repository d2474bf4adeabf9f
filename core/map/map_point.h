#pragma once
// A 3D landmark of one map. Owned by its Map and (strongly) by the keyframe slots
// that observe it; it refers back to those keyframes only weakly. Thread-safe:
// one mutex guards the mutable state (see docs/map_model.md for the lock order).
#include <Eigen/Core>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/features/descriptor.h"
#include "core/common/ids.h"
#include "core/map/object_counters.h"
#include "core/map/observer_record.h"

namespace orbatlas {

class KeyFrame;

// The outcome of an observation edit (KeyFrame::try_add_observation,
// replace_if_holds). The check and the edit happen under the keyframe's and the
// point's mutexes, so "the slot was free" and "the point went in" are one step:
// tracking and local mapping may edit the same keyframe at once and the one that
// loses simply learns it here (nothing changed unless kDone).
enum class SlotEdit {
  kDone,
  kBad,              // the keyframe or the point is culled
  kSlotTaken,        // the slot already holds a point (add)
  kSlotChanged,      // the slot no longer holds the expected point (replace_if_holds)
  kAlreadyObserved,  // the point already sits in another slot of this keyframe
};
const char* to_string(SlotEdit edit);

struct MapPointData {
  Eigen::Vector3d p_w = Eigen::Vector3d::Zero();     // position in the map's world
  Descriptor descriptor{};                           // representative descriptor
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // mean viewing direction (unit)
  float min_distance = 0.0f, max_distance = 0.0f;    // scale-invariance range, metres
};

// One keyframe observing the point (a snapshot; the keyframe may be gone since).
struct MapPointObservation {
  KeyframeId keyframe = 0;
  std::weak_ptr<KeyFrame> kf;
  std::size_t slot = 0;
  int level = 0;
};

class MapPoint {
 public:
  static std::shared_ptr<MapPoint> create(MapPointId id, MapId map, MapPointData data,
                                          std::shared_ptr<ObjectCounters> counters);
  MapPoint(const MapPoint&) = delete;
  MapPoint& operator=(const MapPoint&) = delete;

  MapPointId id() const { return id_; }
  // The map holding it; changes only when a merge moves it (Map::absorb).
  MapId map_id() const { return map_id_.load(); }
  bool is_bad() const { return bad_.load(); }
  // A hint to bring what projecting this point reads (its state, geometry and
  // descriptor) into the cache: a walk over many points asks it of the next
  // few before reading the first.
  void prefetch() const {
    __builtin_prefetch(&bad_);
    __builtin_prefetch(&data_.p_w);
    __builtin_prefetch(&data_.normal);
    __builtin_prefetch(&data_.max_distance);
  }

  Eigen::Vector3d p_w() const;
  void set_p_w(const Eigen::Vector3d& p_w);
  Descriptor descriptor() const;
  void set_descriptor(const Descriptor& descriptor);
  Eigen::Vector3d normal() const;
  void set_normal(const Eigen::Vector3d& normal);
  float min_distance() const;
  float max_distance() const;
  void set_distances(float min_distance, float max_distance);
  // Position, normal and distances read together under one lock (projecting a
  // point into a frame needs all four).
  struct Geometry {
    Eigen::Vector3d p_w, normal;
    float min_distance, max_distance;
  };
  Geometry geometry() const;

  // Reference keyframe (weak); when it stops observing the point, the first
  // remaining observer (lowest id) takes over. Null when none is left.
  std::shared_ptr<KeyFrame> reference_keyframe() const;
  std::optional<KeyframeId> reference_keyframe_id() const;
  void set_reference_keyframe(const std::shared_ptr<KeyFrame>& keyframe);

  // Tracking statistics (ORB-SLAM's visible / found).
  void increase_visible(int n = 1) { visible_.fetch_add(n); }
  void increase_found(int n = 1) { found_.fetch_add(n); }
  int visible() const { return visible_.load(); }
  int found() const { return found_.load(); }
  double found_ratio() const;

  // Observations are edited through KeyFrame::add_observation / erase_slot / replace.
  std::vector<MapPointObservation> observations() const;  // by keyframe id
  // f(keyframe id, weak keyframe) for each observer, by keyframe id, under the
  // point's lock: no copy of the list (tracking's local map asks this of every
  // tracked point each frame). f must not call into this point, take a lock,
  // or make the weak link strong (docs/map_model.md, "Threads and locks").
  template <class F>
  void for_each_observer(F&& f) const {
    std::lock_guard lock(mutex_);
    for (const auto& [kf_id, record] : observers_) f(kf_id, record.keyframe);
  }
  std::size_t observation_count() const;
  std::optional<std::size_t> slot_in(KeyframeId keyframe) const;
  // Number of observers other than `exclude` with level <= max_level, counting
  // stops at `enough` (the redundancy scan's inner loop).
  int observers_up_to_level(int max_level, KeyframeId exclude, int enough) const;

 private:
  friend class KeyFrame;  // attach / detach under the keyframe's lock
  friend class Map;       // mark_bad when culling, map_id_ when merging

  MapPoint(MapPointId id, MapId map, MapPointData data, std::shared_ptr<ObjectCounters> counters);

  // kBad or kAlreadyObserved change nothing; decided under the point's mutex.
  SlotEdit attach_observer(KeyframeId keyframe, ObserverRecord record);
  void detach_observer(KeyframeId keyframe);
  void mark_bad();

  LifetimeToken token_;  // first member: destroyed last (see object_counters.h)
  const MapPointId id_;
  std::atomic<MapId> map_id_;  // set by Map::absorb
  std::atomic<bool> bad_{false};
  std::atomic<int> visible_{1}, found_{1};

  mutable std::mutex mutex_;  // guards everything below
  MapPointData data_;
  ObserverRecords observers_;
  std::weak_ptr<KeyFrame> reference_;
  std::optional<KeyframeId> reference_id_;
};

}  // namespace orbatlas
