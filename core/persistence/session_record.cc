#include "core/persistence/session_record.h"

#include "core/persistence/sql_columns.h"

namespace orbatlas {

void write_session_record(SqlConnection& db, SessionId id, const SessionRecord& record) {
  db.prepare_statement(
        "INSERT INTO session_records(session_id, frames, tracked, keyframes, rejected_frames, skipped_frames, "
        "imu_samples, mode, config, outcome, ended_by, error, maps_busy_frames) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, "
        "?8, ?9, ?10, ?11, ?12, ?13) ON CONFLICT(session_id) DO UPDATE SET frames = excluded.frames, tracked = "
        "excluded.tracked, keyframes = excluded.keyframes, rejected_frames = excluded.rejected_frames, "
        "skipped_frames = excluded.skipped_frames, imu_samples = excluded.imu_samples, mode = excluded.mode, "
        "config = excluded.config, outcome = excluded.outcome, ended_by = excluded.ended_by, error = excluded.error, "
        "maps_busy_frames = excluded.maps_busy_frames")
      ->bind_int64(1, sql_id(id))
      .bind_int64(2, sql_id(record.frames))
      .bind_int64(3, sql_id(record.tracked))
      .bind_int64(4, sql_id(record.keyframes))
      .bind_int64(5, sql_id(record.rejected_frames))
      .bind_int64(6, sql_id(record.skipped_frames))
      .bind_int64(7, sql_id(record.imu_samples))
      .bind_text(8, record.mode)
      .bind_text(9, record.config)
      .bind_text(10, record.outcome)
      .bind_text(11, record.ended_by)
      .bind_text(12, record.error)
      .bind_int64(13, sql_id(record.maps_busy_frames))
      .run();
}

std::map<SessionId, SessionRecord> read_session_records(SqlConnection& db) {
  std::map<SessionId, SessionRecord> out;
  const std::unique_ptr<SqlStatement> rows = db.prepare_statement(
      "SELECT session_id, frames, tracked, keyframes, rejected_frames, skipped_frames, imu_samples, mode, config, "
      "outcome, ended_by, error, maps_busy_frames FROM session_records ORDER BY session_id");
  while (rows->step()) {
    SessionRecord r;
    r.frames = id_column(*rows, 1);
    r.tracked = id_column(*rows, 2);
    r.keyframes = id_column(*rows, 3);
    r.rejected_frames = id_column(*rows, 4);
    r.skipped_frames = id_column(*rows, 5);
    r.imu_samples = id_column(*rows, 6);
    r.mode = rows->text(7);
    r.config = rows->text(8);
    r.outcome = rows->text(9);
    r.ended_by = rows->text(10);
    r.error = rows->text(11);
    r.maps_busy_frames = id_column(*rows, 12);
    out[id_column(*rows, 0)] = std::move(r);
  }
  return out;
}

}  // namespace orbatlas
