#include "core/persistence/job_rows.h"

#include "core/persistence/sql_columns.h"

namespace orbatlas {

void write_job(SqlConnection& db, const StoredJob& job) {
  const std::unique_ptr<SqlStatement> statement = db.prepare_statement(
      "INSERT INTO upload_jobs(id, name, state, session_id, created_ns, archive_bytes, frames_total, frames_done, "
      "tracked, rejected, ate_rmse_m, error) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12) "
      "ON CONFLICT(id) DO UPDATE SET name = excluded.name, state = excluded.state, session_id = excluded.session_id, "
      "archive_bytes = excluded.archive_bytes, frames_total = excluded.frames_total, "
      "frames_done = excluded.frames_done, tracked = excluded.tracked, rejected = excluded.rejected, "
      "ate_rmse_m = excluded.ate_rmse_m, error = excluded.error");
  SqlStatement& upsert = *statement;
  upsert.bind_int64(1, sql_id(job.id)).bind_text(2, job.name).bind_text(3, job.state);
  if (job.session) {
    upsert.bind_int64(4, sql_id(*job.session));
  } else {
    upsert.bind_null(4);
  }
  upsert.bind_int64(5, job.created_ns)
      .bind_int64(6, sql_id(job.archive_bytes))
      .bind_int64(7, sql_id(job.frames_total))
      .bind_int64(8, sql_id(job.frames_done))
      .bind_int64(9, sql_id(job.tracked))
      .bind_int64(10, sql_id(job.rejected));
  if (job.ate_rmse_m) {
    upsert.bind_real(11, *job.ate_rmse_m);
  } else {
    upsert.bind_null(11);
  }
  upsert.bind_text(12, job.error).run();
}

namespace {

constexpr const char* kJobColumns =
    "SELECT id, name, state, session_id, created_ns, archive_bytes, frames_total, frames_done, tracked, rejected, "
    "ate_rmse_m, error FROM upload_jobs";

StoredJob job_from_row(SqlStatement& rows) {
  StoredJob j;
  j.id = id_column(rows, 0);
  j.name = rows.text(1);
  j.state = rows.text(2);
  if (!rows.is_null(3)) j.session = id_column(rows, 3);
  j.created_ns = rows.int64(4);
  j.archive_bytes = id_column(rows, 5);
  j.frames_total = id_column(rows, 6);
  j.frames_done = id_column(rows, 7);
  j.tracked = id_column(rows, 8);
  j.rejected = id_column(rows, 9);
  if (!rows.is_null(10)) j.ate_rmse_m = rows.real(10);
  j.error = rows.text(11);
  return j;
}

}  // namespace

std::vector<StoredJob> read_jobs(SqlConnection& db) {
  std::vector<StoredJob> jobs;
  const std::unique_ptr<SqlStatement> statement = db.prepare_statement(std::string(kJobColumns) + " ORDER BY id");
  while (statement->step()) jobs.push_back(job_from_row(*statement));
  return jobs;
}

std::optional<StoredJob> read_job(SqlConnection& db, std::uint64_t id) {
  const std::unique_ptr<SqlStatement> statement = db.prepare_statement(std::string(kJobColumns) + " WHERE id = ?1");
  statement->bind_int64(1, sql_id(id));
  if (!statement->step()) return std::nullopt;
  return job_from_row(*statement);
}

}  // namespace orbatlas
