#pragma once
// The atlas as database rows: one snapshot of every map turned into the values
// of the rows that save_atlas and checkpoints write (docs/schema.md), each with
// a content hash of its mutable columns. A checkpointer keeps the rows it last
// committed (with the objects dropped) and writes only what differs
// (atlas_row_sync.h).
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/map/atlas.h"
#include "core/persistence/session_info.h"

namespace orbatlas {

inline constexpr MapPointId kNoMapPoint = ~MapPointId{0};  // an empty slot

struct KeyframeRow {
  KeyframeId id = 0;
  // For the immutable columns and the features blob, read when the row is
  // inserted; null in committed rows (nothing is kept alive by a checkpointer).
  std::shared_ptr<const KeyFrame> keyframe;
  MapId map = 0;
  Pose3 T_w_b;
  double units = 1.0;                // KeyFrame::units
  std::optional<KeyframeId> parent;  // NULL: a root, or the parent is not in the snapshot
  std::optional<SessionId> session;  // none: the stored value stays (NULL for a new row)
  // Of map, T_w_b, units and parent: the other columns never change for an id (the
  // features are immutable), and a keyframe's session is set once.
  std::uint64_t hash = 0;
  std::vector<MapPointId> slots;               // observations by slot; kNoMapPoint when empty
  std::vector<CovisibilityEdge> covisibility;  // as this keyframe holds them, by neighbour id
  // The inertial link (keyframe_inertial_links), when its previous keyframe is
  // in the snapshot; the increments are dropped with the keyframe after a
  // commit, and inertial_hash (previous id and increments) says when to rewrite.
  std::optional<KeyframeId> inertial_previous;
  std::shared_ptr<const Preintegration> inertial_increments;
  std::optional<Pose3> inertial_T_c_i;  // the IMU in the camera (InertialLink::T_c_i)
  std::uint64_t inertial_hash = 0;
  // The keyframe's IMU state (keyframe_imu_states), with a hash of it.
  std::optional<KeyFrame::ImuState> imu;
  std::uint64_t imu_hash = 0;
};

// A map's inertial initialisation (map_inertial_states).
struct MapInertialRow {
  MapId map = 0;
  Map::InertialState state;
  std::uint64_t hash = 0;  // of every column
};

struct MapPointRow {
  MapPointId id = 0;
  MapId map = 0;
  MapPointData data;
  std::optional<KeyframeId> reference;
  int visible = 0, found = 0;
  std::uint64_t hash = 0;  // of every column
};

struct CulledKeyframeRow {
  MapId map = 0;
  Map::CulledKeyframe anchor;
  std::uint64_t hash = 0;  // of every column
};

// The atlas row (allocator and active map); saved_ns and checkpoint_seq are
// bookkeeping of each write, not content.
struct AtlasMetaRow {
  std::uint64_t next_keyframe_id = 0, next_map_point_id = 0, next_map_id = 0;
  std::optional<MapId> active_map;
  std::uint64_t hash() const;
};

using LoopEdge = std::pair<KeyframeId, KeyframeId>;  // lower id first: stored once

struct AtlasRows {
  std::vector<MapId> maps;                // ascending
  std::vector<KeyframeRow> keyframes;     // by id
  std::vector<MapPointRow> points;        // by id
  std::vector<CulledKeyframeRow> culled;  // by id
  std::vector<LoopEdge> loop_edges;       // ascending, unique
  std::vector<MapInertialRow> inertial;   // by map
  std::optional<AtlasMetaRow> meta;       // none: nothing written yet
  // The maps removed from the atlas so far (merged into others), read with the
  // snapshot: a map is either in `maps` or here, never both or neither.
  std::vector<MapId> removed_maps;

  // Releases the keyframes (after a commit: the rows are then only compared).
  void drop_objects();
};

// The session a keyframe was made in, or none to keep what is stored.
using KeyframeSessionOf = std::function<std::optional<SessionId>(KeyframeId)>;

// One snapshot of every map's containers, then of its culled keyframes. A link
// (observation, covisibility, loop edge, parent, reference keyframe) is kept
// only when both ends are in the snapshot, so the rows are consistent even when
// other threads cull meanwhile (exact when nobody edits the atlas). The
// allocator is read last: every id in the rows is below its next ids.
AtlasRows collect_atlas_rows(const Atlas& atlas, const KeyframeSessionOf& session_of);

// The rows of the maps `keep` says yes to (a loop edge goes with its first
// keyframe's map); the atlas row stays, its active map only when kept. Several writers of one database each
// write only their own maps (AtlasCheckpointWriter).
AtlasRows rows_of_maps(AtlasRows rows, const std::function<bool(MapId)>& keep);

// One digest per map of every row it has (keyframes with their observations,
// covisibility, links and IMU states; points; culled keyframes; inertial
// state; loop edges), so that a writer can tell which maps a checkpoint
// changed (replicas of one database: the others read those maps again).
std::unordered_map<MapId, std::uint64_t> map_digests(const AtlasRows& rows);

}  // namespace orbatlas
