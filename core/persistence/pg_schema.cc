#include "core/persistence/pg_schema.h"

#include "core/common/error.h"
#include "persistence_generated/embedded_pg_schema.h"

namespace orbatlas {
namespace {

// pg_advisory_lock's key for migrations (any constant the atlas owns).
constexpr std::int64_t kMigrationLockKey = 0x6f72626174;  // "orbat"

// A database migrated when PostgreSQL had its own list (schema/postgres/NNN_*.sql,
// 002-008 its replica tables, 001 SQLite's schema 8) has the row
// (2, '002_atlas_writer.sql'). Its rows 2..8 become 9..15 under their new names,
// and SQLite's steps 2..8, which its 001 already held, are recorded as done.
void renumber_separate_list(PgDb& db, TimestampNs now_ns) {
  if (read_postgres_schema_version(db) == 0 ||
      db.query_int64("SELECT count(*) FROM schema_migrations WHERE version = 2 AND name = '002_atlas_writer.sql'") == 0)
    return;
  const auto steps = postgres_schema_migrations();
  PgTransaction transaction(db);
  for (int old_version = 8; old_version >= 2; --old_version) {
    const SchemaMigration& now = steps[static_cast<std::size_t>(old_version + kSeparateNumberingShift - 1)];
    db.prepare("UPDATE schema_migrations SET version = ?1, name = ?2 WHERE version = ?3")
        .bind_int64(1, now.version)
        .bind_text(2, now.name)
        .bind_int64(3, old_version)
        .run();
  }
  db.prepare("UPDATE schema_migrations SET name = ?1 WHERE version = 1").bind_text(1, steps[0].name).run();
  for (int version = 2; version <= 8; ++version)
    db.prepare("INSERT INTO schema_migrations(version, name, applied_ns) VALUES (?1, ?2, ?3)")
        .bind_int64(1, version)
        .bind_text(2, steps[static_cast<std::size_t>(version - 1)].name)
        .bind_int64(3, now_ns)
        .run();
  transaction.commit();
}

}  // namespace

std::span<const SchemaMigration> postgres_schema_migrations() {
  return persistence_detail::kEmbeddedPostgresMigrations;
}

int latest_postgres_schema_version() { return postgres_schema_migrations().back().version; }

int read_postgres_schema_version(PgDb& db) {
  if (db.query_int64("SELECT to_regclass('schema_migrations') IS NOT NULL") == 0) return 0;
  const std::int64_t version = db.query_int64("SELECT coalesce(max(version), 0) FROM schema_migrations");
  ORBATLAS_DATA_CHECK(version >= 0, db.description() << ": negative schema version " << version);
  return static_cast<int>(version);
}

void check_postgres_schema_supported(PgDb& db) {
  // Whether schema_migrations exists and how many tables there are, in one
  // statement (one snapshot): another replica may commit the first migration
  // between two statements, and "no schema_migrations" then "16 tables" would
  // refuse the atlas as another application's database.
  PgStatement tables = db.prepare(
      "SELECT count(*) FILTER (WHERE table_name = 'schema_migrations'), count(*) FROM information_schema.tables "
      "WHERE table_schema = current_schema()");
  ORBATLAS_CHECK(tables.step(), db.description() << ": cannot list the database's tables");
  const bool migrated = tables.int64(0) > 0;
  const std::int64_t table_count = tables.int64(1);
  tables.reset();
  ORBATLAS_DATA_CHECK(migrated || table_count == 0, db.description()
                                                        << ": a PostgreSQL database that is not an orbatlas atlas ("
                                                        << table_count << " tables but no schema_migrations)");
  if (!migrated) return;
  // Once there, schema_migrations stays: its version is read on its own.
  const int version = read_postgres_schema_version(db);
  ORBATLAS_DATA_CHECK(version <= latest_postgres_schema_version(),
                      db.description() << ": atlas schema version " << version
                                       << " is newer than this build understands (up to "
                                       << latest_postgres_schema_version() << "); use a newer orbatlas");
}

void migrate_postgres_schema(PgDb& db, TimestampNs now_ns) {
  check_postgres_schema_supported(db);
  if (read_postgres_schema_version(db) >= latest_postgres_schema_version()) return;
  // Replicas may start together on an empty database: one migrates, the
  // others wait. The lock is the session's, taken before each migration's
  // transaction starts: a transaction that waited for it inside could still
  // see the tables as they were when it began (PostgreSQL reads its catalog
  // changes at a transaction's start), and create them a second time.
  db.prepare("SELECT pg_advisory_lock(?1)").bind_int64(1, kMigrationLockKey).run();
  struct Unlock {
    PgDb& db;
    ~Unlock() {
      try {
        db.prepare("SELECT pg_advisory_unlock(?1)").bind_int64(1, kMigrationLockKey).run();
      } catch (const std::exception&) {
        // The connection is gone, and its session lock with it.
      }
    }
  } unlock{db};
  renumber_separate_list(db, now_ns);
  for (const SchemaMigration& migration : postgres_schema_migrations()) {
    if (read_postgres_schema_version(db) >= migration.version) continue;  // another replica migrated it
    PgTransaction transaction(db);
    if (!migration.sql.empty()) db.exec(migration.sql);  // empty: SQLite's step only
    db.prepare("INSERT INTO schema_migrations(version, name, applied_ns) VALUES (?1, ?2, ?3)")
        .bind_int64(1, migration.version)
        .bind_text(2, migration.name)
        .bind_int64(3, now_ns)
        .run();
    transaction.commit();
  }
}

}  // namespace orbatlas
