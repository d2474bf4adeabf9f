#pragma once
// One lazily opened PostgreSQL connection that a failure drops, for the
// replica tables' small classes (MapOwnership, SharedJobQueue, SharedMerges):
// the next call connects again, so a database that restarts is reached again.
#include <memory>
#include <string>

#include "core/persistence/pg_db.h"

namespace orbatlas {

// Runs `work(connection)` on `db` (opened to `location` first when null). An
// exception drops the connection and is rethrown. The caller holds the lock
// that guards `db`.
template <class Work>
auto on_pg_connection(std::unique_ptr<PgDb>& db, const std::string& location, Work work) {
  try {
    if (!db) db = std::make_unique<PgDb>(location);
    return work(*db);
  } catch (const std::exception&) {
    db.reset();
    throw;
  }
}

}  // namespace orbatlas
