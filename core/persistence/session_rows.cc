// AtlasStore: sessions and their camera rigs.
#include <map>

#include "core/common/error.h"
#include "core/persistence/atlas_store.h"
#include "core/persistence/blob_codec.h"
#include "core/persistence/session_rows.h"
#include "core/persistence/sql_columns.h"

namespace orbatlas {
namespace {

CameraModel parse_camera_model(const std::string& name, const std::string& who) {
  for (const CameraModel model : {CameraModel::kPinholeRadTan, CameraModel::kKannalaBrandt})
    if (name == camera_model_name(model)) return model;
  throw DataError(who + ": unknown camera model '" + name + "'");
}

constexpr const char* kSessionColumns = "SELECT id, name, sensor, created_ns FROM sessions";

SessionInfo session_from_row(const SqlStatement& row, const std::string& file) {
  SessionInfo s;
  s.id = id_column(row, 0);
  s.name = row.text(1);
  const std::string sensor = row.text(2);
  const auto type = parse_sensor_type(sensor);
  ORBATLAS_DATA_CHECK(type.has_value(), file << ": session " << s.id << ": unknown sensor type '" << sensor << "'");
  s.sensor = *type;
  s.created_ns = row.int64(3);
  return s;
}

// Cameras of the listed sessions, in camera_index order.
void read_cameras(SqlConnection& db, std::map<SessionId, SessionInfo>& sessions) {
  const std::unique_ptr<SqlStatement> statement = db.prepare_statement(
      "SELECT session_id, camera_index, model, fx, fy, cx, cy, distortion, width, height, rate_hz, "
      "qw, qx, qy, qz, tx, ty, tz FROM cameras WHERE session_id = ?1 ORDER BY camera_index");
  SqlStatement& row = *statement;
  for (auto& [id, session] : sessions) {
    row.bind_int64(1, sql_id(id));
    while (row.step()) {
      const std::int64_t index = row.int64(1);
      const std::string who = db.description() + ": session " + std::to_string(id) + " camera " + std::to_string(index);
      ORBATLAS_DATA_CHECK(index == static_cast<std::int64_t>(session.cameras.size()),
                          who << ": camera indices are not 0, 1, ...");
      CameraCalibration c;
      c.model = parse_camera_model(row.text(2), who);
      c.fx = row.real(3);
      c.fy = row.real(4);
      c.cx = row.real(5);
      c.cy = row.real(6);
      c.distortion = decode_doubles(row.blob(7), who);
      c.width = static_cast<int>(row.int64(8));
      c.height = static_cast<int>(row.int64(9));
      c.rate_hz = row.real(10);
      c.T_b_c = pose_columns(row, 11);
      session.cameras.push_back(std::move(c));
    }
    row.reset();
  }
}

}  // namespace

void write_session_rows(SqlConnection& db, const SessionInfo& session) {
  const std::int64_t id = sql_id(session.id);
  // An upsert, not INSERT OR REPLACE, which would cascade-delete the trajectory.
  db.prepare_statement(
        "INSERT INTO sessions(id, name, sensor, created_ns) VALUES (?1, ?2, ?3, ?4) "
        "ON CONFLICT(id) DO UPDATE SET name = excluded.name, sensor = excluded.sensor, "
        "created_ns = excluded.created_ns")
      ->bind_int64(1, id)
      .bind_text(2, session.name)
      .bind_text(3, sensor_type_name(session.sensor))
      .bind_int64(4, session.created_ns)
      .run();
  db.prepare_statement("DELETE FROM cameras WHERE session_id = ?1")->bind_int64(1, id).run();
  const std::unique_ptr<SqlStatement> statement = db.prepare_statement(
      "INSERT INTO cameras(session_id, camera_index, model, fx, fy, cx, cy, distortion, width, height, rate_hz, "
      "qw, qx, qy, qz, tx, ty, tz) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, "
      "?18)");
  SqlStatement& insert = *statement;
  for (std::size_t i = 0; i < session.cameras.size(); ++i) {
    const CameraCalibration& c = session.cameras[i];
    insert.bind_int64(1, id)
        .bind_int64(2, static_cast<std::int64_t>(i))
        .bind_text(3, camera_model_name(c.model))
        .bind_real(4, c.fx)
        .bind_real(5, c.fy)
        .bind_real(6, c.cx)
        .bind_real(7, c.cy)
        .bind_blob(8, encode_doubles(c.distortion))
        .bind_int64(9, c.width)
        .bind_int64(10, c.height)
        .bind_real(11, c.rate_hz);
    bind_pose(insert, 12, c.T_b_c);
    insert.run();
    insert.reset();
  }
}

void AtlasStore::save_session(const SessionInfo& session) {
  SqlTransaction transaction(*db_);
  write_session_rows(*db_, session);
  transaction.commit();
}

void AtlasStore::save_session_record(SessionId session, const SessionRecord& record) {
  SqlTransaction transaction(*db_);
  write_session_record(*db_, session, record);
  transaction.commit();
}

std::optional<SessionInfo> AtlasStore::load_session(SessionId id) {
  SqlTransaction transaction(*db_, SqlTransaction::Mode::kRead);
  std::map<SessionId, SessionInfo> sessions;
  {
    const std::unique_ptr<SqlStatement> row = db_->prepare_statement(std::string(kSessionColumns) + " WHERE id = ?1");
    row->bind_int64(1, sql_id(id));
    if (!row->step()) return std::nullopt;
    sessions.emplace(id, session_from_row(*row, location()));
  }
  read_cameras(*db_, sessions);
  transaction.commit();
  return std::move(sessions.begin()->second);
}

std::vector<SessionInfo> AtlasStore::load_sessions() {
  SqlTransaction transaction(*db_, SqlTransaction::Mode::kRead);
  std::map<SessionId, SessionInfo> sessions;
  {
    const std::unique_ptr<SqlStatement> row = db_->prepare_statement(std::string(kSessionColumns) + " ORDER BY id");
    while (row->step()) {
      SessionInfo s = session_from_row(*row, location());
      sessions.emplace(s.id, std::move(s));
    }
  }
  read_cameras(*db_, sessions);
  transaction.commit();
  std::vector<SessionInfo> out;
  for (auto& [id, s] : sessions) out.push_back(std::move(s));
  return out;
}

}  // namespace orbatlas
