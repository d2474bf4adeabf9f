#pragma once
// The versioned schema: schema/NNN_name/sqlite.sql (and postgres.sql for
// PostgreSQL, pg_schema.h: one numbered list for both), compiled into the library
// at build time, applied in order as forward migrations. PRAGMA user_version holds
// the version of the last one applied (0: an empty database). See docs/schema.md.
#include <span>
#include <string_view>

#include "core/common/timestamp.h"
#include "core/persistence/sqlite_db.h"

namespace orbatlas {

struct SchemaMigration {
  int version = 0;        // NNN of the folder name; 1, 2, ... without gaps
  std::string_view name;  // folder name, e.g. "001_initial"
  // The script; empty when the step is the other database's only. An SQLite
  // script ends with PRAGMA user_version = NNN.
  std::string_view sql;
};

// The migrations of this build, by version.
std::span<const SchemaMigration> schema_migrations();
int latest_schema_version();

// PRAGMA user_version. The first read of a file: throws DataError for a file
// that is not an SQLite database.
int read_schema_version(SqliteDb& db);

// Read-only: throws DataError when the database was written by a newer build
// (user_version above latest_schema_version()), or when it has version 0 but
// already holds tables (an SQLite file that is not an orbatlas atlas).
void check_schema_version_supported(SqliteDb& db);

// Applies every migration above the database's version, each in its own write
// transaction that also records it in schema_migrations; a migration another
// connection applied meanwhile is skipped; a step without an SQLite script only
// moves the version. Throws Error when a script leaves user_version at another
// value than its number.
void migrate_schema(SqliteDb& db, TimestampNs now_ns);

}  // namespace orbatlas
