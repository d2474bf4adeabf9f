#pragma once
// The prepared statements that write the atlas's rows, one method per kind of
// row, shared by save_atlas (everything) and checkpoints (what changed). Used
// inside a write transaction; destroy it before COMMIT (it finalizes its
// statements). Upserts are INSERT ... ON CONFLICT DO UPDATE, never INSERT OR
// REPLACE, which would delete the old row and cascade to what references it.
// The SQL is what SQLite and PostgreSQL both accept (sql_dialect.h for the one
// difference), so the writer runs on either connection (sql_connection.h).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>

#include "core/map/frame_anchor.h"
#include "core/persistence/atlas_rows.h"
#include "core/persistence/sql_connection.h"

namespace orbatlas {

class AtlasRowWriter {
 public:
  explicit AtlasRowWriter(SqlConnection& db);

  // The session stored for each keyframe that has one.
  std::unordered_map<KeyframeId, SessionId> stored_keyframe_sessions();

  // Everything stored in the map: keyframes, map points and culled keyframes,
  // cascading to observations and graph edges. The maps row stays.
  void delete_map_contents(MapId map);
  void upsert_map(MapId map, TimestampNs saved_ns);
  // A map merged into another: its remaining contents and its maps row.
  void delete_map(MapId map);

  void insert_keyframe(const KeyframeRow& row);  // every column; row.keyframe must be set
  void update_keyframe(const KeyframeRow& row);  // map, pose and parent (and the session, if the row has one)
  void delete_keyframe(KeyframeId id);
  // The keyframe's inertial link as the row has it (written, or deleted when none).
  void write_inertial_link(const KeyframeRow& row);
  void upsert_map_inertial(const MapInertialRow& row);
  // The keyframe's IMU state as the row has it (written, or deleted when none).
  void write_imu_state(const KeyframeRow& row);
  void delete_map_inertial(MapId map);
  void upsert_map_point(const MapPointRow& row);
  void delete_map_point(MapPointId id);
  void upsert_culled_keyframe(const CulledKeyframeRow& row);
  void delete_culled_keyframe(KeyframeId id);

  void insert_observation(KeyframeId keyframe, std::size_t slot, MapPointId point);
  void delete_observation(KeyframeId keyframe, std::size_t slot);
  void upsert_covisibility(KeyframeId keyframe, const CovisibilityEdge& edge);
  void delete_covisibility(KeyframeId keyframe, KeyframeId other);
  void insert_loop_edge(const LoopEdge& edge);
  void delete_loop_edge(const LoopEdge& edge);

  void upsert_trajectory(SessionId session, const FrameAnchor& anchor);
  void delete_trajectory(SessionId session, TimestampNs t_ns);
  void delete_session_trajectory(SessionId session);

  // The atlas row: allocator (max with what is stored: it only moves forward),
  // active map, saved_ns, and checkpoint_seq + 1. Returns the new sequence number.
  std::int64_t write_meta(const AtlasMetaRow& meta, TimestampNs saved_ns);

 private:
  using Statement = std::unique_ptr<SqlStatement>;
  const std::string database_;
  Statement stored_sessions_, delete_culled_of_map_, delete_points_of_map_, delete_keyframes_of_map_, delete_map_,
      upsert_map_, insert_keyframe_, update_keyframe_, delete_keyframe_, upsert_point_, delete_point_, upsert_culled_,
      upsert_inertial_link_, delete_inertial_link_, upsert_imu_state_, delete_imu_state_, upsert_map_inertial_,
      delete_map_inertial_, delete_culled_, insert_observation_, delete_observation_, upsert_covisibility_,
      delete_covisibility_, insert_loop_edge_, delete_loop_edge_, upsert_trajectory_, delete_trajectory_,
      delete_session_trajectory_, write_meta_, read_sequence_;
};

}  // namespace orbatlas
