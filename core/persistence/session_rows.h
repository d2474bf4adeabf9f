#pragma once
// The rows of a session (sessions + cameras), written inside the caller's
// transaction: AtlasStore::save_session and a checkpointer's first checkpoint.
#include "core/persistence/session_info.h"
#include "core/persistence/sql_connection.h"

namespace orbatlas {

// Inserts or replaces the session row and its cameras (its trajectory and
// keyframe references stay). Throws Error on values the schema refuses.
void write_session_rows(SqlConnection& db, const SessionInfo& session);

}  // namespace orbatlas
