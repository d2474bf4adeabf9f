#pragma once
// The atlas's schema in PostgreSQL: schema/NNN_name/postgres.sql (one numbered
// list with SQLite's, schema_migrations.h), compiled into the library and applied
// in order as forward migrations, each in one transaction that records it in
// schema_migrations; a step without a PostgreSQL script (SQLite's only: 001
// creates SQLite's schema 8 at once) is recorded alone. PostgreSQL has no PRAGMA
// user_version: the version is schema_migrations' largest row (0 for a database
// without the table). The tables are SQLite's in PostgreSQL's dialect
// (tests/persistence/test_pg_schema.cc compares them column by column).
#include <span>

#include "core/common/timestamp.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/schema_migrations.h"

namespace orbatlas {

std::span<const SchemaMigration> postgres_schema_migrations();
int latest_postgres_schema_version();

int read_postgres_schema_version(PgDb& db);

// Throws DataError when the database was written by a newer build, or holds
// tables but no orbatlas schema (another application's database).
void check_postgres_schema_supported(PgDb& db);

// Applies every migration above the database's version. Replicas starting
// together are serialised by a session-level advisory lock; a migration
// another one applied meanwhile is skipped. A database numbered as before the
// two lists became one (its 002-008 PostgreSQL's own steps, now 009-015) is
// renumbered first, in one transaction.
void migrate_postgres_schema(PgDb& db, TimestampNs now_ns);
// PostgreSQL's own steps 002..008 of its separate list are 009..015 of the one list.
inline constexpr int kSeparateNumberingShift = 7;

}  // namespace orbatlas
