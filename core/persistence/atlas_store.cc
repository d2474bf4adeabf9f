// AtlasStore: opening (validation before any write, then WAL and migrations) and
// the atlas metadata row. Saving and loading are in atlas_save.cc / atlas_load.cc,
// sessions and trajectories in session_rows.cc / trajectory_rows.cc.
#include "core/persistence/atlas_store.h"

#include "core/common/error.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sql_columns.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

// The vocabulary hash an existing atlas was built with; empty when the database
// has no atlas row yet (new, or interrupted between migration and first row).
// Every schema version keeps atlas.vocabulary_hash: this runs before migrating.
std::string stored_vocabulary_hash(SqliteDb& db) {
  if (read_schema_version(db) == 0) return {};
  SqliteStatement row = db.prepare("SELECT vocabulary_hash FROM atlas WHERE id = 1");
  return row.step() ? row.text(0) : std::string();
}

void check_vocabulary(SqliteDb& db, const std::string& vocabulary_hash) {
  const std::string stored = stored_vocabulary_hash(db);
  ORBATLAS_DATA_CHECK(stored.empty() || stored == vocabulary_hash,
                      db.path().string() << ": the atlas was built with vocabulary " << stored << ", not "
                                         << vocabulary_hash
                                         << "; its words (bag-of-words vectors, keyframe database) would not match");
}

}  // namespace

AtlasStore AtlasStore::open(const std::filesystem::path& path, const std::string& vocabulary_hash) {
  ORBATLAS_CHECK(!vocabulary_hash.empty(), path.string() << ": opening an atlas needs the vocabulary hash");
  SqliteDb db(path);
  // 1. Read-only checks: a file we refuse is left exactly as it was.
  check_schema_version_supported(db);  // the first read: also rejects non-SQLite files
  check_vocabulary(db, vocabulary_hash);

  // 2. Connection settings, then the first writes.
  db.exec("PRAGMA foreign_keys = ON");  // per connection, off by default in SQLite
  {
    // WAL: readers do not block the writer and a crash mid-save leaves the last
    // committed atlas intact. Persistent: recorded in the file header.
    SqliteStatement mode = db.prepare("PRAGMA journal_mode = WAL");
    ORBATLAS_CHECK(mode.step() && mode.text(0) == "wal", path.string()
                                                             << ": cannot switch the database to WAL journal mode");
  }
  const TimestampNs now = unix_time_ns();
  migrate_schema(db, now);
  {
    SqliteTransaction transaction(db);
    check_vocabulary(db, vocabulary_hash);  // again under the write lock: another process may have created it
    db.prepare("INSERT OR IGNORE INTO atlas(id, vocabulary_hash, created_ns) VALUES (1, ?1, ?2)")
        .bind_text(1, vocabulary_hash)
        .bind_int64(2, now)
        .run();
    transaction.commit();
  }
  AtlasStore store(std::move(db));
  store.read_metadata();
  return store;
}

void AtlasStore::read_metadata() {
  SqliteStatement row = db_.prepare("SELECT vocabulary_hash, created_ns FROM atlas WHERE id = 1");
  ORBATLAS_DATA_CHECK(row.step(), path().string() << ": the atlas row is missing");
  vocabulary_hash_ = row.text(0);
  created_ns_ = row.int64(1);
}

int AtlasStore::schema_version() { return read_schema_version(db_); }

std::int64_t AtlasStore::checkpoint_sequence() {
  return db_.query_int64("SELECT checkpoint_seq FROM atlas WHERE id = 1");
}

std::vector<MapId> AtlasStore::stored_map_ids() {
  std::vector<MapId> ids;
  SqliteStatement rows = db_.prepare("SELECT id FROM maps ORDER BY id");
  while (rows.step()) ids.push_back(id_column(rows, 0));
  return ids;
}

}  // namespace orbatlas
