#include "core/persistence/schema_migrations.h"

#include "core/common/error.h"
#include "core/common/log.h"
#include "persistence_generated/embedded_schema.h"

namespace orbatlas {

std::span<const SchemaMigration> schema_migrations() { return persistence_detail::kEmbeddedMigrations; }

int latest_schema_version() { return schema_migrations().back().version; }

int read_schema_version(SqliteDb& db) {
  const std::int64_t version = db.query_int64("PRAGMA user_version");
  ORBATLAS_DATA_CHECK(version >= 0, db.path().string() << ": negative schema version (user_version " << version << ")");
  return static_cast<int>(version);
}

void check_schema_version_supported(SqliteDb& db) {
  const int version = read_schema_version(db);
  ORBATLAS_DATA_CHECK(version <= latest_schema_version(), db.path().string()
                                                              << ": atlas schema version " << version
                                                              << " is newer than this build understands (up to "
                                                              << latest_schema_version() << "); use a newer orbatlas");
  if (version == 0) {
    const std::int64_t objects = db.query_int64("SELECT count(*) FROM sqlite_schema");
    ORBATLAS_DATA_CHECK(objects == 0, db.path().string() << ": an SQLite database that is not an orbatlas atlas ("
                                                         << objects << " schema objects but user_version 0)");
  }
}

void migrate_schema(SqliteDb& db, TimestampNs now_ns) {
  // Foreign keys are off while a migration runs (SQLite's procedure for
  // rebuilding a table: dropping the old one must not cascade into the rows
  // that refer to it); they are checked before it commits, and the
  // connection's setting comes back afterwards, also when it fails.
  const bool foreign_keys = db.query_int64("PRAGMA foreign_keys") != 0;
  struct RestoreForeignKeys {
    SqliteDb& db;
    bool on;
    ~RestoreForeignKeys() {
      if (!on) return;
      try {
        db.exec("PRAGMA foreign_keys = ON");
      } catch (const std::exception& e) {
        log_warn(db.path().string() + ": foreign keys not turned on again after migrating: " + e.what());
      }
    }
  } restore{db, foreign_keys};
  for (const SchemaMigration& migration : schema_migrations()) {
    if (read_schema_version(db) >= migration.version) continue;
    db.exec("PRAGMA foreign_keys = OFF");  // outside a transaction: inside one it does nothing
    SqliteTransaction transaction(db);
    // Re-read under the write lock: another connection may have migrated meanwhile.
    if (read_schema_version(db) >= migration.version) continue;
    if (migration.sql.empty()) {
      db.exec("PRAGMA user_version = " + std::to_string(migration.version));  // PostgreSQL's step only
    } else {
      db.exec(migration.sql);
    }
    const int reached = read_schema_version(db);
    ORBATLAS_CHECK(reached == migration.version,
                   db.path().string() << ": migration " << migration.name << " left user_version at " << reached);
    const std::int64_t dangling = db.query_int64("SELECT count(*) FROM pragma_foreign_key_check");
    ORBATLAS_CHECK(dangling == 0, db.path().string() << ": migration " << migration.name << " left " << dangling
                                                     << " rows referring to rows that do not exist");
    db.prepare("INSERT INTO schema_migrations(version, name, applied_ns) VALUES (?1, ?2, ?3)")
        .bind_int64(1, migration.version)
        .bind_text(2, migration.name)
        .bind_int64(3, now_ns)
        .run();
    transaction.commit();
  }
}

}  // namespace orbatlas
