// AtlasStore::save_atlas: every map of the atlas replaces its stored rows, in one
// write transaction (all or nothing).
#include <algorithm>
#include <unordered_set>

#include "core/common/error.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/sql_columns.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

// The prepared statements of one save, reused for every row.
class AtlasWriter {
 public:
  AtlasWriter(SqliteDb& db, TimestampNs now_ns)
      : now_ns_(now_ns),
        stored_sessions_(db.prepare("SELECT id, session_id FROM keyframes WHERE map_id = ?1 AND session_id IS NOT NULL")),
        // Points first: deleting them cascades to their observations before the
        // keyframes go (which cascades to covisibility and loop edges).
        delete_points_(db.prepare("DELETE FROM map_points WHERE map_id = ?1")),
        delete_keyframes_(db.prepare("DELETE FROM keyframes WHERE map_id = ?1")),
        // An upsert, not INSERT OR REPLACE: replacing the row would cascade-delete
        // whatever still references it.
        upsert_map_(db.prepare("INSERT INTO maps(id, saved_ns) VALUES (?1, ?2) "
                               "ON CONFLICT(id) DO UPDATE SET saved_ns = excluded.saved_ns")),
        insert_keyframe_(db.prepare(
            "INSERT INTO keyframes(id, map_id, session_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
            "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, parent_id, slot_count, features) "
            "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20, ?21)")),
        insert_point_(db.prepare(
            "INSERT INTO map_points(id, map_id, x, y, z, nx, ny, nz, min_distance, max_distance, descriptor, "
            "reference_keyframe_id, visible, found) "
            "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)")),
        insert_observation_(db.prepare("INSERT INTO observations(keyframe_id, slot, map_point_id) VALUES (?1, ?2, ?3)")),
        insert_covisibility_(
            db.prepare("INSERT INTO covisibility(keyframe_id, other_id, weight) VALUES (?1, ?2, ?3)")),
        // Loop edges are symmetric: each pair is met from both ends.
        insert_loop_edge_(db.prepare("INSERT OR IGNORE INTO loop_edges(keyframe_id, other_id) VALUES (?1, ?2)")) {}

  void write_map(const Map& map, const AtlasSaveOptions& options) {
    const std::int64_t map_id = sql_id(map.id());
    std::unordered_map<KeyframeId, SessionId> sessions = previous_sessions(map_id);
    for (const auto& [kf, session] : options.keyframe_sessions) sessions[kf] = session;

    delete_points_.bind_int64(1, map_id).run();
    delete_points_.reset();
    delete_keyframes_.bind_int64(1, map_id).run();
    delete_keyframes_.reset();
    upsert_map_.bind_int64(1, map_id).bind_int64(2, now_ns_).run();
    upsert_map_.reset();

    // One snapshot of each container; every link is written only if both ends
    // are in it (an object culled meanwhile is in neither the rows nor the links).
    const auto keyframes = map.keyframes();
    const auto points = map.map_points();
    std::unordered_set<KeyframeId> kf_ids;
    std::unordered_set<MapPointId> point_ids;
    for (const auto& kf : keyframes) kf_ids.insert(kf->id());
    for (const auto& mp : points) point_ids.insert(mp->id());

    for (const auto& kf : keyframes) write_keyframe(*kf, map_id, sessions, kf_ids);
    for (const auto& mp : points) write_point(*mp, map_id, kf_ids);
    for (const auto& kf : keyframes) write_links(*kf, kf_ids, point_ids);
  }

 private:
  std::unordered_map<KeyframeId, SessionId> previous_sessions(std::int64_t map_id) {
    std::unordered_map<KeyframeId, SessionId> out;
    stored_sessions_.bind_int64(1, map_id);
    while (stored_sessions_.step()) out[id_column(stored_sessions_, 0)] = id_column(stored_sessions_, 1);
    stored_sessions_.reset();
    return out;
  }

  void write_keyframe(const KeyFrame& kf, std::int64_t map_id, const std::unordered_map<KeyframeId, SessionId>& sessions,
                      const std::unordered_set<KeyframeId>& kf_ids) {
    SqliteStatement& s = insert_keyframe_;
    s.bind_int64(1, sql_id(kf.id())).bind_int64(2, map_id);
    if (const auto it = sessions.find(kf.id()); it != sessions.end()) s.bind_int64(3, sql_id(it->second));
    s.bind_int64(4, kf.timestamp_ns());
    bind_pose(s, 5, kf.T_w_b());
    bind_pose(s, 12, kf.T_b_c());
    if (const auto parent = kf.parent_id(); parent && kf_ids.contains(*parent)) s.bind_int64(19, sql_id(*parent));
    s.bind_int64(20, static_cast<std::int64_t>(kf.slot_count()));
    // KeyFrame exposes depth / u_right per slot; monocular keyframes have none.
    std::vector<float> depth, u_right;
    if (kf.is_stereo()) {
      depth.resize(kf.slot_count());
      u_right.resize(kf.slot_count());
      for (std::size_t i = 0; i < kf.slot_count(); ++i) {
        depth[i] = kf.depth(i);
        u_right[i] = kf.u_right(i);
      }
    }
    s.bind_blob(21, encode_features(kf.features(), depth, u_right));
    s.run();
    s.reset();
  }

  void write_point(const MapPoint& mp, std::int64_t map_id, const std::unordered_set<KeyframeId>& kf_ids) {
    SqliteStatement& s = insert_point_;
    const Eigen::Vector3d p = mp.p_w(), n = mp.normal();
    s.bind_int64(1, sql_id(mp.id())).bind_int64(2, map_id);
    for (int i = 0; i < 3; ++i) s.bind_real(3 + i, p[i]);
    for (int i = 0; i < 3; ++i) s.bind_real(6 + i, n[i]);
    s.bind_real(9, mp.min_distance()).bind_real(10, mp.max_distance());
    s.bind_blob(11, encode_descriptor(mp.descriptor()));
    if (const auto ref = mp.reference_keyframe_id(); ref && kf_ids.contains(*ref)) s.bind_int64(12, sql_id(*ref));
    s.bind_int64(13, mp.visible()).bind_int64(14, mp.found());
    s.run();
    s.reset();
  }

  void write_links(const KeyFrame& kf, const std::unordered_set<KeyframeId>& kf_ids,
                   const std::unordered_set<MapPointId>& point_ids) {
    const std::int64_t id = sql_id(kf.id());
    const auto slots = kf.slots();
    for (std::size_t slot = 0; slot < slots.size(); ++slot) {
      const auto& mp = slots[slot];
      if (!mp || mp->is_bad() || !point_ids.contains(mp->id())) continue;
      insert_observation_.bind_int64(1, id).bind_int64(2, static_cast<std::int64_t>(slot)).bind_int64(3, sql_id(mp->id()));
      insert_observation_.run();
      insert_observation_.reset();
    }
    for (const CovisibilityEdge& edge : kf.connections()) {
      if (!kf_ids.contains(edge.keyframe)) continue;
      insert_covisibility_.bind_int64(1, id).bind_int64(2, sql_id(edge.keyframe)).bind_int64(3, edge.weight);
      insert_covisibility_.run();
      insert_covisibility_.reset();
    }
    for (const KeyframeId other : kf.loop_edge_ids()) {
      if (!kf_ids.contains(other)) continue;
      insert_loop_edge_.bind_int64(1, sql_id(std::min(kf.id(), other))).bind_int64(2, sql_id(std::max(kf.id(), other)));
      insert_loop_edge_.run();
      insert_loop_edge_.reset();
    }
  }

  const TimestampNs now_ns_;
  SqliteStatement stored_sessions_, delete_points_, delete_keyframes_, upsert_map_, insert_keyframe_, insert_point_,
      insert_observation_, insert_covisibility_, insert_loop_edge_;
};

}  // namespace

void AtlasStore::save_atlas(const Atlas& atlas, const AtlasSaveOptions& options) {
  const TimestampNs now = unix_time_ns();
  SqliteTransaction transaction(db_);
  {
    AtlasWriter writer(db_, now);  // its statements are finalized before COMMIT
    for (const auto& map : atlas.maps()) writer.write_map(*map, options);
  }
  // The allocator only moves forward, also across saves of different atlases.
  const IdAllocator& ids = atlas.ids();
  const auto active = atlas.active_map();
  SqliteStatement meta = db_.prepare(
      "UPDATE atlas SET saved_ns = ?1, next_keyframe_id = max(next_keyframe_id, ?2), "
      "next_map_point_id = max(next_map_point_id, ?3), next_map_id = max(next_map_id, ?4), active_map_id = ?5 "
      "WHERE id = 1");
  meta.bind_int64(1, now)
      .bind_int64(2, sql_id(ids.peek(IdKind::keyframe)))
      .bind_int64(3, sql_id(ids.peek(IdKind::map_point)))
      .bind_int64(4, sql_id(ids.peek(IdKind::map)));
  if (active) meta.bind_int64(5, sql_id(active->id()));
  meta.run();
  transaction.commit();
}

}  // namespace orbatlas
