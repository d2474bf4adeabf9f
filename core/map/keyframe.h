#pragma once
// A keyframe of one map: immutable features, a mutable pose, one map point slot
// per keypoint (strong: KeyFrame -> MapPoint), and graph links to other keyframes
// (covisibility, spanning tree, loop edges) that are all weak, so reference
// counting alone frees culled keyframes. Thread-safe: one mutex per keyframe
// guards its mutable state; see docs/map_model.md for the lock order.
#include <atomic>
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "core/common/flat_id_set.h"
#include "core/common/ids.h"
#include "core/imu/preintegration.h"
#include "core/map/keyframe_data.h"
#include "core/map/map_point.h"
#include "core/map/object_counters.h"

namespace orbatlas {

inline constexpr int kCovisibilityMinWeight = 15;  // ORB-SLAM's threshold on shared points

struct CovisibilityEdge {
  KeyframeId keyframe = 0;
  int weight = 0;  // number of map points both keyframes observe
};

class KeyFrame : public std::enable_shared_from_this<KeyFrame> {
 public:
  // Checks that stereo vectors are empty or index-aligned with the keypoints.
  static std::shared_ptr<KeyFrame> create(KeyframeId id, MapId map, KeyFrameData data,
                                          std::shared_ptr<ObjectCounters> counters);
  ~KeyFrame();  // detaches from the map points it still observes
  KeyFrame(const KeyFrame&) = delete;
  KeyFrame& operator=(const KeyFrame&) = delete;

  // --- immutable ---
  KeyframeId id() const { return id_; }
  // The map holding it; changes only when a merge moves it (Map::absorb).
  MapId map_id() const { return map_id_.load(); }
  std::int64_t timestamp_ns() const { return data_.timestamp_ns; }
  const ImageFeatures& features() const { return data_.features; }
  std::size_t slot_count() const { return data_.features.keypoints.size(); }
  const Keypoint& keypoint(std::size_t slot) const;
  bool is_stereo() const { return !data_.depth.empty(); }
  // Some keypoint has a measured depth (stereo or RGB-D): the keyframe was
  // made in metric units. A monocular keyframe has none.
  bool has_depth() const { return has_depth_; }
  float depth(std::size_t slot) const;    // -1 when unmatched or monocular
  float u_right(std::size_t slot) const;  // -1 when unmatched or monocular
  const BowVector& bow() const { return data_.bow; }
  const FeatureVector& feature_vector() const { return data_.feature_vector; }
  const FeatureGrid& grid() const { return data_.grid; }
  const Pose3& T_b_c() const { return data_.T_b_c; }

  bool is_bad() const { return bad_.load(); }  // culled

  // --- pose ---
  Pose3 T_w_b() const;
  Pose3 T_w_c() const;
  void set_T_w_b(const Pose3& T_w_b);
  // The scale of lengths about the keyframe since it was made (1 at first): a
  // map's rescale multiplies it for every keyframe, a Sim(3) loop correction by
  // the keyframe's own scale change. Poses kept relative to the keyframe
  // (FrameAnchor) are stored divided by it, so they follow every later change
  // of scale (docs/map_model.md); always 1 in metric maps.
  double units() const;
  void scale_units(double factor);  // Error unless finite and > 0
  void set_units(double units);     // loading a map

  // --- observations (both sides: the slot and the map point's observer list) ---
  // Puts the point in a free slot, as one step against concurrent edits: what
  // stood in the way is the result (nothing changed unless kDone). Throws only
  // for a slot out of range or a null point. Use this wherever another thread
  // may edit the keyframe (tracking, local mapping, loop closing, merging).
  SlotEdit try_add_observation(std::size_t slot, const std::shared_ptr<MapPoint>& map_point);
  // For code that owns the keyframe alone (loading, tests): false (nothing
  // changed) when this keyframe or the point is bad; throws when the slot is
  // taken or the point already sits in another slot.
  bool add_observation(std::size_t slot, const std::shared_ptr<MapPoint>& map_point);
  // Empties the slot; returns the point that was there (null if none).
  std::shared_ptr<MapPoint> erase_slot(std::size_t slot);
  // erase_slot, only if the slot still holds `map_point` (culling, fusion).
  void erase_slot_if_holds(std::size_t slot, const std::shared_ptr<MapPoint>& map_point);
  // Puts `replacement` in the slot only if it still holds `expected` (fusion):
  // kSlotChanged when another edit got there first.
  SlotEdit replace_if_holds(std::size_t slot, const std::shared_ptr<MapPoint>& expected,
                            const std::shared_ptr<MapPoint>& replacement);
  // Puts `map_point` in the slot instead of whatever is there (same rules as
  // add_observation; single-owner code).
  bool replace(std::size_t slot, const std::shared_ptr<MapPoint>& map_point);
  std::shared_ptr<MapPoint> map_point(std::size_t slot) const;
  std::vector<std::shared_ptr<MapPoint>> slots() const;       // index-aligned, nulls included
  std::vector<std::shared_ptr<MapPoint>> map_points() const;  // non-null slots
  // Calls f(const std::shared_ptr<MapPoint>&) for each non-null slot under this
  // keyframe's mutex, without copying the slots (tracking's hot loops). f may
  // lock a map point (the lock order's next step) but no keyframe, and must not
  // change this keyframe's slots.
  template <typename F>
  void for_each_map_point(F&& f) const {
    std::lock_guard lock(mutex_);
    for (const auto& mp : slots_)
      if (mp) f(mp);
  }
  // Calls f(const std::shared_ptr<MapPoint>&) for each non-null slot whose
  // point's id was not in `seen` yet (and puts it there), under this keyframe's
  // mutex: a local map's points taken once each over many keyframes, the points
  // several of them observe passed over by id without touching the point. The
  // same rules for f as for_each_map_point. The points are taken eight at a
  // time, their memory fetched for all eight before f sees the first: f's work
  // on a point begins with a cache miss (its state and geometry) and takes the
  // point's lock, which would otherwise wait out each miss in turn.
  template <typename F>
  void for_each_unseen_map_point(FlatIdSet& seen, F&& f) const {
    constexpr std::size_t kBatch = 8;
    std::size_t batch[kBatch];
    std::size_t n = 0;
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < slot_ids_.size(); ++i) {
      if (slot_ids_[i] == kInvalidMapPointId || !seen.insert(slot_ids_[i])) continue;
      slots_[i]->prefetch();
      batch[n++] = i;
      if (n == kBatch) {
        for (std::size_t k = 0; k < n; ++k) f(slots_[batch[k]]);
        n = 0;
      }
    }
    for (std::size_t k = 0; k < n; ++k) f(slots_[batch[k]]);
  }
  int map_point_count() const { return map_point_count_.load(); }
  // Incremental redundancy (redundancy_tracker.h): points of this keyframe that
  // kRedundancyMinObservers other keyframes see at the same or a finer level.
  int redundant_map_point_count() const { return redundant_->load(); }

  // --- covisibility (weak links) ---
  // Recomputes the weights to every keyframe sharing map points with this one; keeps
  // those >= min_weight, or the best one if none is, and mirrors them in the neighbours.
  void update_connections(int min_weight = kCovisibilityMinWeight);
  void add_connection(const std::shared_ptr<KeyFrame>& other, int weight);
  void erase_connection(KeyframeId other);
  int weight(KeyframeId other) const;                                           // 0 when not connected
  std::vector<CovisibilityEdge> connections() const;                            // weight descending, then id ascending
  std::vector<std::shared_ptr<KeyFrame>> best_covisibles(std::size_t n) const;  // live, not bad

  // --- spanning tree (weak links) ---
  void set_parent(const std::shared_ptr<KeyFrame>& parent);  // null makes it a root
  std::shared_ptr<KeyFrame> parent() const;
  std::optional<KeyframeId> parent_id() const;              // kept after culling (the parent may be gone)
  std::vector<std::shared_ptr<KeyFrame>> children() const;  // by id
  std::vector<KeyframeId> child_ids() const;

  // --- loop edges (weak links, both ways) ---
  void add_loop_edge(const std::shared_ptr<KeyFrame>& other);
  std::vector<KeyframeId> loop_edge_ids() const;

  // --- inertial chain (visual-inertial sessions; weak links, both ways) ---
  // The IMU preintegrated from the session's previous keyframe in this map to
  // this one. Culling a keyframe of the chain joins its two increments
  // (Map::cull_keyframe), so the chain skips it.
  struct InertialLink {
    std::weak_ptr<KeyFrame> previous;
    KeyframeId previous_id = 0;
    std::shared_ptr<const Preintegration> from_previous;
    // The IMU in this keyframe's camera (the session's rig; the same for every
    // link of one chain). Unset: a link stored before the atlas kept it, whose
    // IMU the map's settings place (InertialWindowOptions::T_b_i).
    std::optional<Pose3> T_c_i;
  };
  void set_inertial_link(const std::shared_ptr<KeyFrame>& previous, std::shared_ptr<const Preintegration> from_previous,
                         std::optional<Pose3> T_c_i);
  std::optional<InertialLink> inertial_link() const;
  std::shared_ptr<KeyFrame> inertial_next() const;  // the keyframe whose link leads here (null: none)
  void clear_inertial_link();                       // the chain breaks before this keyframe

  // The keyframe's IMU state, once its map is inertially initialised: the
  // IMU's velocity expressed in the IMU's own frame (so that moving the map or
  // the keyframe carries it along) and the biases; set by tracking when the
  // keyframe is made and refined by visual-inertial bundle adjustment.
  struct ImuState {
    Eigen::Vector3d v_i = Eigen::Vector3d::Zero();
    ImuBias bias;
  };
  void set_imu_state(const ImuState& state);
  std::optional<ImuState> imu_state() const;

 private:
  friend class Map;  // culling

  struct Link {
    std::weak_ptr<KeyFrame> keyframe;
    int weight = 0;
  };

  KeyFrame(KeyframeId id, MapId map, KeyFrameData data, std::shared_ptr<ObjectCounters> counters);

  void check_slot(std::size_t slot) const;
  // Attaches this keyframe to `map_point` for `slot`; mutex_ must be held.
  SlotEdit attach_locked(std::size_t slot, const std::shared_ptr<MapPoint>& map_point);
  // Puts `map_point` in the slot in place of what is there when that is
  // `expected` (any point when `any`); mutex_ must be held; the old point is
  // moved to `released` (dropped by the caller after unlocking).
  SlotEdit swap_locked(std::size_t slot, const std::shared_ptr<MapPoint>& expected, bool any,
                       const std::shared_ptr<MapPoint>& map_point, std::shared_ptr<MapPoint>& released);
  void rebuild_order_locked();
  void add_child(KeyframeId id, std::weak_ptr<KeyFrame> child);
  void erase_child(KeyframeId id);
  void erase_loop_edge(KeyframeId id);
  void mark_bad();
  std::map<KeyframeId, Link> take_connections();
  std::map<KeyframeId, std::weak_ptr<KeyFrame>> take_loop_edges();

  LifetimeToken token_;  // first member: destroyed last (see object_counters.h)
  const KeyframeId id_;
  std::atomic<MapId> map_id_;  // set by Map::absorb
  const KeyFrameData data_;    // data_.T_w_b is only the initial pose; T_w_b_ is current
  const bool has_depth_;
  const std::shared_ptr<std::atomic<int>> redundant_;
  std::atomic<bool> bad_{false};
  std::atomic<int> map_point_count_{0};

  mutable std::mutex mutex_;  // guards everything below
  Pose3 T_w_b_;
  double units_ = 1.0;
  std::vector<std::shared_ptr<MapPoint>> slots_;
  std::vector<MapPointId> slot_ids_;  // slots_[i]'s id, kInvalidMapPointId where empty
  std::map<KeyframeId, Link> connections_;
  std::vector<CovisibilityEdge> ordered_;  // connections_ by weight descending, id ascending
  std::weak_ptr<KeyFrame> parent_;
  std::optional<KeyframeId> parent_id_;
  std::map<KeyframeId, std::weak_ptr<KeyFrame>> children_;
  std::map<KeyframeId, std::weak_ptr<KeyFrame>> loop_edges_;
  std::optional<InertialLink> inertial_;
  std::weak_ptr<KeyFrame> inertial_next_;
  std::optional<ImuState> imu_state_;
};

// Median depth of the points a keyframe observes, in its camera (ORB-SLAM's
// ComputeSceneMedianDepth); -1 when it observes none.
double median_scene_depth(const KeyFrame& keyframe);

}  // namespace orbatlas
