#pragma once
// What a session did, as its last checkpoint stored it (table session_records,
// schemas 16, 17): its counts and how it ended, so that a session read back by a later
// run reports what it had, not what its stored trajectory implies.
#include <cstddef>
#include <map>
#include <string>

#include "core/common/ids.h"
#include "core/persistence/sql_connection.h"

namespace orbatlas {

struct SessionRecord {
  std::size_t frames = 0, tracked = 0, keyframes = 0, rejected_frames = 0, skipped_frames = 0, imu_samples = 0;
  std::size_t maps_busy_frames = 0;  // answered untracked: the maps were held past the session's bound
  std::string mode;                  // "map", "localize" ("" when not known)
  std::string config;                // the config it was started with ("" for inline settings)
  // "active" (the last checkpoint saw it running: the server stopped before its
  // end was stored), "finished" or "failed".
  std::string outcome = "active";
  std::string ended_by;  // who ended it when not the client ("idle_timeout", "shutdown")
  std::string error;     // why it failed

  bool operator==(const SessionRecord&) const = default;
};

// Inserts or replaces the session's record, inside the caller's transaction
// (the session's row must exist). Throws Error on values the schema refuses.
void write_session_record(SqlConnection& db, SessionId id, const SessionRecord& record);
// Every stored record, by session.
std::map<SessionId, SessionRecord> read_session_records(SqlConnection& db);

}  // namespace orbatlas
