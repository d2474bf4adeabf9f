#include "core/persistence/atlas_row_writer.h"

#include "core/common/error.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/inertial_blob.h"
#include "core/persistence/sql_columns.h"
#include "core/persistence/sql_dialect.h"

namespace orbatlas {
namespace {

// Runs a statement whose parameters are bound, then makes it ready again.
void run_once(SqlStatement& s) {
  s.run();
  s.reset();
}

void bind_optional_id(SqlStatement& s, int index, const std::optional<std::uint64_t>& id) {
  if (id) s.bind_int64(index, sql_id(*id));  // unbound parameters are NULL
}

std::string features_blob(const KeyFrame& kf) {
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
  return encode_features(kf.features(), depth, u_right);
}

}  // namespace

AtlasRowWriter::AtlasRowWriter(SqlConnection& db)
    : database_(db.description()),
      stored_sessions_(db.prepare_statement("SELECT id, session_id FROM keyframes WHERE session_id IS NOT NULL")),
      delete_culled_of_map_(db.prepare_statement("DELETE FROM culled_keyframes WHERE map_id = ?1")),
      // Points first: deleting them cascades to their observations before the
      // keyframes go (which cascades to covisibility and loop edges).
      delete_points_of_map_(db.prepare_statement("DELETE FROM map_points WHERE map_id = ?1")),
      delete_keyframes_of_map_(db.prepare_statement("DELETE FROM keyframes WHERE map_id = ?1")),
      delete_map_(db.prepare_statement("DELETE FROM maps WHERE id = ?1")),
      upsert_map_(db.prepare_statement("INSERT INTO maps(id, saved_ns) VALUES (?1, ?2) "
                                       "ON CONFLICT(id) DO UPDATE SET saved_ns = excluded.saved_ns")),
      insert_keyframe_(db.prepare_statement(
          "INSERT INTO keyframes(id, map_id, session_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, "
          "c_qw, c_qx, c_qy, c_qz, c_tx, c_ty, c_tz, parent_id, slot_count, features, units) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20, ?21, "
          "?22)")),
      // The mutable columns only: the features blob (most of the bytes) is never rewritten.
      update_keyframe_(db.prepare_statement(
          "UPDATE keyframes SET qw = ?2, qx = ?3, qy = ?4, qz = ?5, tx = ?6, ty = ?7, tz = ?8, parent_id = ?9, "
          "session_id = coalesce(?10, session_id), map_id = ?11, units = ?12 WHERE id = ?1")),
      delete_keyframe_(db.prepare_statement("DELETE FROM keyframes WHERE id = ?1")),
      upsert_point_(db.prepare_statement(
          "INSERT INTO map_points(id, map_id, x, y, z, nx, ny, nz, min_distance, max_distance, descriptor, "
          "reference_keyframe_id, visible, found) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14) "
          "ON CONFLICT(id) DO UPDATE SET map_id = excluded.map_id, x = excluded.x, y = excluded.y, z = excluded.z, "
          "nx = excluded.nx, ny = excluded.ny, nz = excluded.nz, min_distance = excluded.min_distance, "
          "max_distance = excluded.max_distance, descriptor = excluded.descriptor, "
          "reference_keyframe_id = excluded.reference_keyframe_id, visible = excluded.visible, "
          "found = excluded.found")),
      delete_point_(db.prepare_statement("DELETE FROM map_points WHERE id = ?1")),
      upsert_culled_(db.prepare_statement(
          "INSERT INTO culled_keyframes(id, map_id, parent_id, qw, qx, qy, qz, tx, ty, tz, units) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11) "
          "ON CONFLICT(id) DO UPDATE SET map_id = excluded.map_id, parent_id = excluded.parent_id, "
          "qw = excluded.qw, qx = excluded.qx, qy = excluded.qy, qz = excluded.qz, "
          "tx = excluded.tx, ty = excluded.ty, tz = excluded.tz, units = excluded.units")),
      upsert_inertial_link_(db.prepare_statement(
          "INSERT INTO keyframe_inertial_links(keyframe_id, previous_id, increments, c_i_qw, c_i_qx, c_i_qy, c_i_qz, "
          "c_i_tx, c_i_ty, c_i_tz) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10) ON CONFLICT(keyframe_id) DO "
          "UPDATE SET previous_id = excluded.previous_id, increments = excluded.increments, c_i_qw = excluded.c_i_qw, "
          "c_i_qx = excluded.c_i_qx, c_i_qy = excluded.c_i_qy, c_i_qz = excluded.c_i_qz, c_i_tx = excluded.c_i_tx, "
          "c_i_ty = excluded.c_i_ty, c_i_tz = excluded.c_i_tz")),
      delete_inertial_link_(db.prepare_statement("DELETE FROM keyframe_inertial_links WHERE keyframe_id = ?1")),
      upsert_imu_state_(db.prepare_statement(
          "INSERT INTO keyframe_imu_states(keyframe_id, vx, vy, vz, bgx, bgy, bgz, bax, bay, baz) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10) ON CONFLICT(keyframe_id) DO UPDATE SET "
          "vx = excluded.vx, vy = excluded.vy, vz = excluded.vz, bgx = excluded.bgx, bgy = excluded.bgy, "
          "bgz = excluded.bgz, bax = excluded.bax, bay = excluded.bay, baz = excluded.baz")),
      delete_imu_state_(db.prepare_statement("DELETE FROM keyframe_imu_states WHERE keyframe_id = ?1")),
      upsert_map_inertial_(db.prepare_statement(
          "INSERT INTO map_inertial_states(map_id, initialized_at_ns, gx, gy, gz, bgx, bgy, bgz, bax, bay, baz, "
          "keyframes, span_s, refinements, sgx, sgy, sgz, sax, say, saz) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, "
          "?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18, ?19, ?20) "
          "ON CONFLICT(map_id) DO UPDATE SET initialized_at_ns = excluded.initialized_at_ns, gx = excluded.gx, "
          "gy = excluded.gy, gz = excluded.gz, bgx = excluded.bgx, bgy = excluded.bgy, bgz = excluded.bgz, "
          "bax = excluded.bax, bay = excluded.bay, baz = excluded.baz, keyframes = excluded.keyframes, "
          "span_s = excluded.span_s, refinements = excluded.refinements, sgx = excluded.sgx, sgy = excluded.sgy, "
          "sgz = excluded.sgz, sax = excluded.sax, say = excluded.say, saz = excluded.saz")),
      delete_map_inertial_(db.prepare_statement("DELETE FROM map_inertial_states WHERE map_id = ?1")),
      delete_culled_(db.prepare_statement("DELETE FROM culled_keyframes WHERE id = ?1")),
      insert_observation_(
          db.prepare_statement("INSERT INTO observations(keyframe_id, slot, map_point_id) VALUES (?1, ?2, ?3)")),
      delete_observation_(db.prepare_statement("DELETE FROM observations WHERE keyframe_id = ?1 AND slot = ?2")),
      upsert_covisibility_(
          db.prepare_statement("INSERT INTO covisibility(keyframe_id, other_id, weight) VALUES (?1, ?2, ?3) "
                               "ON CONFLICT(keyframe_id, other_id) DO UPDATE SET weight = excluded.weight")),
      delete_covisibility_(db.prepare_statement("DELETE FROM covisibility WHERE keyframe_id = ?1 AND other_id = ?2")),
      insert_loop_edge_(
          db.prepare_statement("INSERT INTO loop_edges(keyframe_id, other_id) VALUES (?1, ?2) ON CONFLICT DO NOTHING")),
      delete_loop_edge_(db.prepare_statement("DELETE FROM loop_edges WHERE keyframe_id = ?1 AND other_id = ?2")),
      upsert_trajectory_(db.prepare_statement(
          "INSERT INTO trajectory(session_id, t_ns, map_id, reference_keyframe_id, qw, qx, qy, qz, tx, ty, tz) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11) "
          "ON CONFLICT(session_id, t_ns) DO UPDATE SET map_id = excluded.map_id, "
          "reference_keyframe_id = excluded.reference_keyframe_id, qw = excluded.qw, qx = excluded.qx, "
          "qy = excluded.qy, qz = excluded.qz, tx = excluded.tx, ty = excluded.ty, tz = excluded.tz")),
      delete_trajectory_(db.prepare_statement("DELETE FROM trajectory WHERE session_id = ?1 AND t_ns = ?2")),
      delete_session_trajectory_(db.prepare_statement("DELETE FROM trajectory WHERE session_id = ?1")),
      write_meta_(db.prepare_statement(
          "UPDATE atlas SET saved_ns = ?1, next_keyframe_id = " + sql_greatest(db.dialect(), "next_keyframe_id", "?2") +
          ", next_map_point_id = " + sql_greatest(db.dialect(), "next_map_point_id", "?3") +
          ", next_map_id = " + sql_greatest(db.dialect(), "next_map_id", "?4") +
          ", active_map_id = ?5, checkpoint_seq = checkpoint_seq + 1 WHERE id = 1")),
      read_sequence_(db.prepare_statement("SELECT checkpoint_seq FROM atlas WHERE id = 1")) {}

std::unordered_map<KeyframeId, SessionId> AtlasRowWriter::stored_keyframe_sessions() {
  std::unordered_map<KeyframeId, SessionId> out;
  while (stored_sessions_->step()) out[id_column(*stored_sessions_, 0)] = id_column(*stored_sessions_, 1);
  stored_sessions_->reset();
  return out;
}

void AtlasRowWriter::delete_map_contents(MapId map) {
  for (SqlStatement* s : {delete_culled_of_map_.get(), delete_points_of_map_.get(), delete_keyframes_of_map_.get()}) {
    s->bind_int64(1, sql_id(map));
    run_once(*s);
  }
}

void AtlasRowWriter::delete_map(MapId map) {
  delete_map_contents(map);
  delete_map_->bind_int64(1, sql_id(map));
  run_once(*delete_map_);
}

void AtlasRowWriter::upsert_map(MapId map, TimestampNs saved_ns) {
  upsert_map_->bind_int64(1, sql_id(map)).bind_int64(2, saved_ns);
  run_once(*upsert_map_);
}

void AtlasRowWriter::insert_keyframe(const KeyframeRow& row) {
  const KeyFrame& kf = *row.keyframe;
  SqlStatement& s = *insert_keyframe_;
  s.bind_int64(1, sql_id(row.id)).bind_int64(2, sql_id(row.map));
  bind_optional_id(s, 3, row.session);
  s.bind_int64(4, kf.timestamp_ns());
  bind_pose(s, 5, row.T_w_b);
  bind_pose(s, 12, kf.T_b_c());
  bind_optional_id(s, 19, row.parent);
  s.bind_int64(20, static_cast<std::int64_t>(kf.slot_count()));
  s.bind_blob(21, features_blob(kf));
  s.bind_real(22, row.units);
  run_once(s);
}

void AtlasRowWriter::update_keyframe(const KeyframeRow& row) {
  SqlStatement& s = *update_keyframe_;
  s.bind_int64(1, sql_id(row.id));
  bind_pose(s, 2, row.T_w_b);
  bind_optional_id(s, 9, row.parent);
  bind_optional_id(s, 10, row.session);
  s.bind_int64(11, sql_id(row.map));
  s.bind_real(12, row.units);
  run_once(s);
}

void AtlasRowWriter::delete_keyframe(KeyframeId id) {
  delete_keyframe_->bind_int64(1, sql_id(id));
  run_once(*delete_keyframe_);
}

void AtlasRowWriter::write_inertial_link(const KeyframeRow& row) {
  if (!row.inertial_previous || !row.inertial_increments) {
    delete_inertial_link_->bind_int64(1, sql_id(row.id));
    run_once(*delete_inertial_link_);
    return;
  }
  SqlStatement& s = *upsert_inertial_link_;
  s.bind_int64(1, sql_id(row.id));
  s.bind_int64(2, sql_id(*row.inertial_previous));
  s.bind_blob(3, encode_increments(*row.inertial_increments));
  if (row.inertial_T_c_i) {
    bind_pose(s, 4, *row.inertial_T_c_i);
  } else {
    for (int i = 4; i < 11; ++i) s.bind_null(i);
  }
  run_once(s);
}

void AtlasRowWriter::write_imu_state(const KeyframeRow& row) {
  if (!row.imu) {
    delete_imu_state_->bind_int64(1, sql_id(row.id));
    run_once(*delete_imu_state_);
    return;
  }
  SqlStatement& s = *upsert_imu_state_;
  s.bind_int64(1, sql_id(row.id));
  int i = 2;
  for (const Eigen::Vector3d* v : {&row.imu->v_i, &row.imu->bias.gyro, &row.imu->bias.accel})
    for (int k = 0; k < 3; ++k) s.bind_real(i++, (*v)[k]);
  run_once(s);
}

void AtlasRowWriter::upsert_map_inertial(const MapInertialRow& row) {
  SqlStatement& s = *upsert_map_inertial_;
  const Map::InertialState& st = row.state;
  s.bind_int64(1, sql_id(row.map));
  s.bind_int64(2, st.initialized_at_ns);
  int i = 3;
  for (const Eigen::Vector3d* v : {&st.gravity_w, &st.bias.gyro, &st.bias.accel})
    for (int k = 0; k < 3; ++k) s.bind_real(i++, (*v)[k]);
  s.bind_int64(12, static_cast<std::int64_t>(st.keyframes));
  s.bind_real(13, st.span_s);
  s.bind_int64(14, static_cast<std::int64_t>(st.refinements));
  i = 15;
  for (const Eigen::Vector3d* v : {&st.scale.gyro, &st.scale.accel})
    for (int k = 0; k < 3; ++k) s.bind_real(i++, (*v)[k]);
  run_once(s);
}

void AtlasRowWriter::delete_map_inertial(MapId map) {
  delete_map_inertial_->bind_int64(1, sql_id(map));
  run_once(*delete_map_inertial_);
}

void AtlasRowWriter::upsert_map_point(const MapPointRow& row) {
  SqlStatement& s = *upsert_point_;
  s.bind_int64(1, sql_id(row.id)).bind_int64(2, sql_id(row.map));
  for (int i = 0; i < 3; ++i) s.bind_real(3 + i, row.data.p_w[i]);
  for (int i = 0; i < 3; ++i) s.bind_real(6 + i, row.data.normal[i]);
  s.bind_real(9, row.data.min_distance).bind_real(10, row.data.max_distance);
  s.bind_blob(11, encode_descriptor(row.data.descriptor));
  bind_optional_id(s, 12, row.reference);
  s.bind_int64(13, row.visible).bind_int64(14, row.found);
  run_once(s);
}

void AtlasRowWriter::delete_map_point(MapPointId id) {
  delete_point_->bind_int64(1, sql_id(id));
  run_once(*delete_point_);
}

void AtlasRowWriter::upsert_culled_keyframe(const CulledKeyframeRow& row) {
  SqlStatement& s = *upsert_culled_;
  s.bind_int64(1, sql_id(row.anchor.id)).bind_int64(2, sql_id(row.map));
  bind_optional_id(s, 3, row.anchor.parent);
  bind_pose(s, 4, row.anchor.T_parent_b);
  s.bind_real(11, row.anchor.units);
  run_once(s);
}

void AtlasRowWriter::delete_culled_keyframe(KeyframeId id) {
  delete_culled_->bind_int64(1, sql_id(id));
  run_once(*delete_culled_);
}

void AtlasRowWriter::insert_observation(KeyframeId keyframe, std::size_t slot, MapPointId point) {
  insert_observation_->bind_int64(1, sql_id(keyframe))
      .bind_int64(2, static_cast<std::int64_t>(slot))
      .bind_int64(3, sql_id(point));
  run_once(*insert_observation_);
}

void AtlasRowWriter::delete_observation(KeyframeId keyframe, std::size_t slot) {
  delete_observation_->bind_int64(1, sql_id(keyframe)).bind_int64(2, static_cast<std::int64_t>(slot));
  run_once(*delete_observation_);
}

void AtlasRowWriter::upsert_covisibility(KeyframeId keyframe, const CovisibilityEdge& edge) {
  upsert_covisibility_->bind_int64(1, sql_id(keyframe)).bind_int64(2, sql_id(edge.keyframe)).bind_int64(3, edge.weight);
  run_once(*upsert_covisibility_);
}

void AtlasRowWriter::delete_covisibility(KeyframeId keyframe, KeyframeId other) {
  delete_covisibility_->bind_int64(1, sql_id(keyframe)).bind_int64(2, sql_id(other));
  run_once(*delete_covisibility_);
}

void AtlasRowWriter::insert_loop_edge(const LoopEdge& edge) {
  insert_loop_edge_->bind_int64(1, sql_id(edge.first)).bind_int64(2, sql_id(edge.second));
  run_once(*insert_loop_edge_);
}

void AtlasRowWriter::delete_loop_edge(const LoopEdge& edge) {
  delete_loop_edge_->bind_int64(1, sql_id(edge.first)).bind_int64(2, sql_id(edge.second));
  run_once(*delete_loop_edge_);
}

void AtlasRowWriter::upsert_trajectory(SessionId session, const FrameAnchor& anchor) {
  SqlStatement& s = *upsert_trajectory_;
  s.bind_int64(1, sql_id(session))
      .bind_int64(2, anchor.t_ns)
      .bind_int64(3, sql_id(anchor.map))
      .bind_int64(4, sql_id(anchor.reference));
  bind_pose(s, 5, anchor.T_ref_b);
  run_once(s);
}

void AtlasRowWriter::delete_trajectory(SessionId session, TimestampNs t_ns) {
  delete_trajectory_->bind_int64(1, sql_id(session)).bind_int64(2, t_ns);
  run_once(*delete_trajectory_);
}

void AtlasRowWriter::delete_session_trajectory(SessionId session) {
  delete_session_trajectory_->bind_int64(1, sql_id(session));
  run_once(*delete_session_trajectory_);
}

std::int64_t AtlasRowWriter::write_meta(const AtlasMetaRow& meta, TimestampNs saved_ns) {
  write_meta_->bind_int64(1, saved_ns)
      .bind_int64(2, sql_id(meta.next_keyframe_id))
      .bind_int64(3, sql_id(meta.next_map_point_id))
      .bind_int64(4, sql_id(meta.next_map_id));
  bind_optional_id(*write_meta_, 5, meta.active_map);
  run_once(*write_meta_);
  ORBATLAS_DATA_CHECK(read_sequence_->step(), database_ << ": the atlas row is missing");
  const std::int64_t sequence = read_sequence_->int64(0);
  read_sequence_->reset();
  return sequence;
}

}  // namespace orbatlas
