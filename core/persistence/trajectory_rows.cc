// AtlasStore: per-session trajectories (tracking's FrameAnchor: each frame
// relative to its reference keyframe, resolved later with Map::keyframe_pose).
#include "core/common/error.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/sql_columns.h"

namespace orbatlas {

void AtlasStore::save_trajectory(SessionId session, const std::vector<FrameAnchor>& anchors) {
  const std::int64_t id = sql_id(session);
  SqlTransaction transaction(*db_);
  {
    const std::unique_ptr<SqlStatement> exists = db_->prepare_statement("SELECT 1 FROM sessions WHERE id = ?1");
    exists->bind_int64(1, id);
    ORBATLAS_CHECK(exists->step(),
                   location() << ": session " << session << " is not stored; save_session before its trajectory");
  }
  db_->prepare_statement("DELETE FROM trajectory WHERE session_id = ?1")->bind_int64(1, id).run();
  const std::unique_ptr<SqlStatement> insert = db_->prepare_statement(
      "INSERT INTO trajectory(session_id, t_ns, map_id, reference_keyframe_id, qw, qx, qy, qz, tx, ty, tz) "
      "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)");
  for (const FrameAnchor& a : anchors) {
    insert->bind_int64(1, id).bind_int64(2, a.t_ns).bind_int64(3, sql_id(a.map)).bind_int64(4, sql_id(a.reference));
    bind_pose(*insert, 5, a.T_ref_b);
    insert->run();  // a repeated timestamp violates the primary key: Error, nothing saved
    insert->reset();
  }
  transaction.commit();
}

std::vector<FrameAnchor> AtlasStore::load_trajectory(SessionId session) {
  std::vector<FrameAnchor> anchors;
  const std::unique_ptr<SqlStatement> row = db_->prepare_statement(
      "SELECT t_ns, map_id, reference_keyframe_id, qw, qx, qy, qz, tx, ty, tz FROM trajectory "
      "WHERE session_id = ?1 ORDER BY t_ns");
  row->bind_int64(1, sql_id(session));
  while (row->step()) {
    FrameAnchor a;
    a.t_ns = row->int64(0);
    a.map = id_column(*row, 1);
    a.reference = id_column(*row, 2);
    a.T_ref_b = pose_columns(*row, 3);
    anchors.push_back(a);
  }
  return anchors;
}

}  // namespace orbatlas
