#pragma once
// One map: the sole container owner of its keyframes and map points. Culling
// removes an object at once, detaches every relation, and leaves reclamation to
// reference counting: the memory is freed when the last thread holding the
// object lets go. See docs/map_model.md for ownership and lock order.
#include <cmath>
#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include "core/map/id_allocator.h"
#include "core/common/ids.h"
#include "core/map/keyframe.h"
#include "core/map/map_point.h"
#include "core/map/object_counters.h"

namespace orbatlas {

class Map {
 public:
  // `ids` and `counters` are the atlas's (shared: a map may outlive its atlas).
  Map(MapId id, std::shared_ptr<IdAllocator> ids, std::shared_ptr<ObjectCounters> counters);
  Map(const Map&) = delete;
  Map& operator=(const Map&) = delete;

  MapId id() const { return id_; }

  // New objects with fresh atlas-wide ids, added to this map.
  std::shared_ptr<KeyFrame> new_keyframe(KeyFrameData data);
  std::shared_ptr<MapPoint> new_map_point(MapPointData data);
  // Existing objects (e.g. loaded with stored ids): the map id must match and the id be new here.
  void add_keyframe(std::shared_ptr<KeyFrame> keyframe);
  void add_map_point(std::shared_ptr<MapPoint> map_point);

  // Null when absent (never added, or culled).
  std::shared_ptr<KeyFrame> keyframe(KeyframeId id) const;
  std::shared_ptr<MapPoint> map_point(MapPointId id) const;
  // Snapshots for other threads, sorted by id.
  std::vector<std::shared_ptr<KeyFrame>> keyframes() const;
  std::vector<std::shared_ptr<MapPoint>> map_points() const;
  std::size_t keyframe_count() const;
  std::size_t map_point_count() const;

  // Remove from the map at once, mark bad, detach every relation and count as
  // culled. False when the id is not in the map. A keyframe's spanning-tree
  // children are reattached like ORB-SLAM's SetBadFlag (to the parent or to a
  // sibling they share more points with).
  bool cull_keyframe(KeyframeId id);
  bool cull_map_point(MapPointId id);

  // Body pose of a keyframe, alive or culled: a culled keyframe is chained through
  // the pose relative to its spanning-tree parent recorded when it was culled (a
  // few bytes per culled keyframe; the keyframe itself is freed), so frame poses
  // anchored to it follow later corrections. Null for an id the map never held.
  std::optional<Pose3> keyframe_pose(KeyframeId id) const;
  // The same with the keyframe's units (KeyFrame::units; a culled keyframe's
  // through its anchors): a pose stored relative to it, divided by those units,
  // is T_w_b * (its rotation, its translation * units).
  struct KeyframePlacement {
    Pose3 T_w_b;
    double units = 1.0;
  };
  std::optional<KeyframePlacement> keyframe_placement(KeyframeId id) const;

  // What a culled keyframe leaves for keyframe_pose, as persisted with the map.
  struct CulledKeyframe {
    KeyframeId id = 0;
    std::optional<KeyframeId> parent;  // none: T_parent_b is the world pose
    // Relative to the parent, its translation divided by the parent's units
    // (so it follows the parent's later changes of scale); a root's is its world pose.
    Pose3 T_parent_b;
    double units = 1.0;  // the culled keyframe's units over its parent's (a root's own units)
  };
  // Snapshot of every culled keyframe's anchor, by id.
  std::vector<CulledKeyframe> culled_keyframes() const;
  // Restores stored anchors (loading a map). Throws when an id is a keyframe of
  // this map or already has an anchor; parents are not checked (they may come later).
  void restore_culled_keyframes(const std::vector<CulledKeyframe>& culled);

  // Moves every keyframe, map point and culled keyframe's anchor of `source`
  // into this map (merging two maps), expressed in this map's world: keyframe
  // poses, points and their viewing directions are transformed by
  // T_this_source; relations between the objects are untouched. `source` is
  // left empty. Both maps' structural edits wait meanwhile; the caller makes
  // sure nobody tracks or maps in either map (server: map leases). Throws when
  // source is this map.
  struct AbsorbCounts {
    std::size_t keyframes = 0, map_points = 0, culled_keyframes = 0;
  };
  AbsorbCounts absorb(Map& source, const Pose3& T_this_source);

  const std::shared_ptr<ObjectCounters>& counters() const { return counters_; }

  // The inertial initialisation of a visual-inertial map: when, the
  // gravity in the map's frame and the IMU biases (those of the newest keyframe
  // once visual-inertial BA runs).
  struct InertialState {
    TimestampNs initialized_at_ns = 0;  // the newest keyframe of the window
    Eigen::Vector3d gravity_w = Eigen::Vector3d::Zero();
    ImuBias bias;
    // The IMU's scale factors as local BA estimates them (zero until then).
    ImuScaleCorrection scale = {};
    std::size_t keyframes = 0;    // in the window of the latest estimate (initialisation or refinement)
    double span_s = 0.0;          // of that window
    std::size_t refinements = 0;  // done since (inertial_initializer.h)

    // Minus gravity's direction: +z after the initialisation, tilted by the
    // refinements (they keep the map's frame); +z when gravity is not set.
    Eigen::Vector3d up() const {
      const double g = gravity_w.norm();
      return g > 0.0 && std::isfinite(g) ? Eigen::Vector3d(-gravity_w / g) : Eigen::Vector3d::UnitZ();
    }
  };
  std::optional<InertialState> inertial_state() const;
  void set_inertial_state(const InertialState& state);
  // The map's IMU disagreed with its vision (mapping/inertial_consistency.h)
  // at keyframe time `at_ns`: tracked and adjusted visually until it is
  // initialised again, from keyframes after that time only.
  void clear_inertial_state(TimestampNs at_ns);
  TimestampNs inertial_cleared_at() const;  // 0: never
  // A full visual-inertial BA of the map is wanted (its inertial state was
  // just set): local mapping asks, the loop closer's background adjustment
  // takes the request (docs/inertial.md). Any thread.
  void request_inertial_adjustment() { inertial_adjustment_requested_.store(true); }
  bool take_inertial_adjustment_request() { return inertial_adjustment_requested_.exchange(false); }

  // Expresses the whole map in a new world frame: every keyframe pose, point,
  // viewing direction and root anchor becomes T_new_old * it, and frame_epoch()
  // moves on (a global BA solved before then is dropped, not applied). For the
  // gravity alignment of a visual-inertial map; the caller holds the atlas's
  // maps exclusive and keeps the map's local mapping from running meanwhile.
  void change_frame(const Pose3& T_new_old);
  std::uint64_t frame_epoch() const { return frame_epoch_.load(); }
  // Scales the whole map about its origin by `s` > 0 (a monocular map made
  // metric by its inertial initialisation, or merged into a metric map):
  // keyframe positions and units, points and their distance bounds, root
  // culled keyframes' anchors, keyframe IMU velocities; frame_epoch() moves on.
  // The same rules as change_frame for the caller.
  void rescale(double s);
  // Whether the map's lengths are metres: it is inertial (initialised) or
  // ever held a keyframe with measured depths (stereo, RGB-D). A monocular
  // map's scale is its own until an IMU or a merge into a metric map gives it
  // one. O(1): place recognition and relocalisation ask it per candidate.
  bool metric_scale() const;
  // Whether a keyframe with measured depths was ever added (metric_scale
  // without an IMU).
  bool measured_depth() const;

 private:
  struct CulledAnchor {
    std::optional<KeyframeId> parent;  // none: T is the world pose
    Pose3 T_parent_b;                  // as CulledKeyframe
    double units = 1.0;
  };

  void reattach_children(const std::shared_ptr<KeyFrame>& culled);

  const MapId id_;
  const std::shared_ptr<IdAllocator> ids_;
  const std::shared_ptr<ObjectCounters> counters_;

  // Serialises structural edits that span several objects (culling, and with it
  // spanning-tree reattachment). Outermost lock: see docs/map_model.md.
  std::mutex structure_mutex_;
  // Guards the two containers only; a leaf lock (nothing is locked under it, and
  // no object is released under it).
  mutable std::mutex objects_mutex_;
  std::unordered_map<MapPointId, std::shared_ptr<MapPoint>> map_points_;
  std::unordered_map<KeyframeId, std::shared_ptr<KeyFrame>> keyframes_;
  std::unordered_map<KeyframeId, CulledAnchor> culled_anchors_;
  std::optional<InertialState> inertial_;   // guarded by objects_mutex_
  TimestampNs inertial_cleared_at_ns_ = 0;  // guarded by objects_mutex_
  bool measured_depth_ = false;             // a keyframe with depths was added; guarded by objects_mutex_
  std::atomic<std::uint64_t> frame_epoch_{0};
  std::atomic<bool> inertial_adjustment_requested_{false};
};

}  // namespace orbatlas
