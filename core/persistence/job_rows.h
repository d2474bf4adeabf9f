#pragma once
// Upload jobs in the atlas database (table upload_jobs, schema 3): written by
// the server's upload workers at every change of state, read at start, so job
// ids stay unique across restarts and an interrupted job is reported.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/common/timestamp.h"
#include "core/persistence/session_info.h"
#include "core/persistence/sql_connection.h"

namespace orbatlas {

struct StoredJob {
  std::uint64_t id = 0;
  std::string name;
  std::string state;  // queued, extracting, running, done, failed, cancelled
  std::optional<SessionId> session;
  TimestampNs created_ns = 0;
  std::uint64_t archive_bytes = 0, frames_total = 0, frames_done = 0, tracked = 0, rejected = 0;
  std::optional<double> ate_rmse_m;
  std::string error;

  bool operator==(const StoredJob&) const = default;
};

// Inserts or replaces the job's row (one statement: its own transaction).
void write_job(SqlConnection& db, const StoredJob& job);
std::vector<StoredJob> read_jobs(SqlConnection& db);                     // by id
std::optional<StoredJob> read_job(SqlConnection& db, std::uint64_t id);  // one row; none when absent

}  // namespace orbatlas
