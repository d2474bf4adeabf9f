#pragma once
// The atlas's schema in PostgreSQL: schema/postgres/NNN_name.sql,
// compiled into the library and applied in order as forward migrations, each
// in one transaction that records it in schema_migrations. PostgreSQL has no
// PRAGMA user_version: the version is schema_migrations' largest row (0 for a
// database without the table). The tables are SQLite's schema 8 in
// PostgreSQL's dialect (tests/test_pg_schema.cc compares them column by column).
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
// together are serialised by a transaction-scoped advisory lock; a migration
// another one applied meanwhile is skipped.
void migrate_postgres_schema(PgDb& db, TimestampNs now_ns);

}  // namespace orbatlas
