// AtlasStore: opening an SQLite file or a PostgreSQL database (validation
// before any write, then WAL and migrations) and the atlas metadata row.
// Saving and loading are in atlas_save.cc / atlas_load.cc, sessions and
// trajectories in session_rows.cc / trajectory_rows.cc.
#include "core/persistence/atlas_store.h"

#include "core/common/error.h"
#include "core/persistence/atlas_location.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/pg_schema.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sql_columns.h"
#include "core/persistence/sqlite_db.h"
#include "core/persistence/wall_clock.h"

namespace orbatlas {
namespace {

// The vocabulary hash in the atlas row; empty when there is no row yet.
std::string atlas_row_vocabulary(SqlConnection& db) {
  const std::unique_ptr<SqlStatement> row = db.prepare_statement("SELECT vocabulary_hash FROM atlas WHERE id = 1");
  return row->step() ? row->text(0) : std::string();
}

void check_vocabulary(const SqlConnection& db, const std::string& stored, const std::string& vocabulary_hash) {
  ORBATLAS_DATA_CHECK(stored.empty() || stored == vocabulary_hash,
                      db.description() << ": the atlas was built with vocabulary " << stored << ", not "
                                       << vocabulary_hash
                                       << "; its words (bag-of-words vectors, keyframe database) would not match");
}

// After migrating: the atlas row, unless there is one. The vocabulary is
// checked after the insert, in its transaction: if another process created
// the row meanwhile, the insert did nothing and the check sees that row
// (SQLite: under the write lock; PostgreSQL: the insert waits for the other
// transaction and the next statement sees its commit).
void create_atlas_row(SqlConnection& db, const std::string& vocabulary_hash, TimestampNs now) {
  SqlTransaction transaction(db);
  db.prepare_statement(
        "INSERT INTO atlas(id, vocabulary_hash, created_ns) VALUES (1, ?1, ?2) ON CONFLICT(id) DO NOTHING")
      ->bind_text(1, vocabulary_hash)
      .bind_int64(2, now)
      .run();
  check_vocabulary(db, atlas_row_vocabulary(db), vocabulary_hash);
  transaction.commit();
}

}  // namespace

AtlasStore AtlasStore::open(const std::filesystem::path& path, const std::string& vocabulary_hash) {
  if (is_postgres_location(path.string())) {
    check_postgres_uri(path.string());
    return open_postgres(path.string(), vocabulary_hash);
  }
  ORBATLAS_CHECK(!vocabulary_hash.empty(), path.string() << ": opening an atlas needs the vocabulary hash");
  auto db = std::make_unique<SqliteDb>(path);
  // 1. Read-only checks: a file we refuse is left exactly as it was. Every
  // schema version keeps atlas.vocabulary_hash: it is read before migrating.
  check_schema_version_supported(*db);  // the first read: also rejects non-SQLite files
  if (read_schema_version(*db) > 0) check_vocabulary(*db, atlas_row_vocabulary(*db), vocabulary_hash);

  // 2. Connection settings, then the first writes.
  db->exec("PRAGMA foreign_keys = ON");  // per connection, off by default in SQLite
  // Statement journals (and temporary tables) in memory: a checkpoint's
  // statements each journal the pages they change for a statement rollback,
  // and in a temporary file that was gigabytes of writes per minute with four
  // live sessions in one map (docs/benchmarks.md).
  db->exec("PRAGMA temp_store = MEMORY");
  {
    // WAL: readers do not block the writer and a crash mid-save leaves the last
    // committed atlas intact. Persistent: recorded in the file header.
    SqliteStatement mode = db->prepare("PRAGMA journal_mode = WAL");
    ORBATLAS_CHECK(mode.step() && mode.text(0) == "wal", path.string()
                                                             << ": cannot switch the database to WAL journal mode");
  }
  const TimestampNs now = unix_time_ns();
  migrate_schema(*db, now);
  create_atlas_row(*db, vocabulary_hash, now);
  AtlasStore store(std::move(db));
  store.read_metadata();
  return store;
}

AtlasStore AtlasStore::open_postgres(const std::string& conninfo, const std::string& vocabulary_hash) {
  ORBATLAS_CHECK(!vocabulary_hash.empty(), "postgresql: opening an atlas needs the vocabulary hash");
  auto db = std::make_unique<PgDb>(conninfo);
  // 1. Read-only checks, as for SQLite: nothing is written to a database we refuse.
  check_postgres_schema_supported(*db);
  if (read_postgres_schema_version(*db) > 0) check_vocabulary(*db, atlas_row_vocabulary(*db), vocabulary_hash);
  // 2. Migrations (under an advisory lock: replicas may start together), the atlas row.
  const TimestampNs now = unix_time_ns();
  migrate_postgres_schema(*db, now);
  create_atlas_row(*db, vocabulary_hash, now);
  AtlasStore store(std::move(db));
  store.read_metadata();
  return store;
}

void AtlasStore::read_metadata() {
  const std::unique_ptr<SqlStatement> row =
      db_->prepare_statement("SELECT vocabulary_hash, created_ns FROM atlas WHERE id = 1");
  ORBATLAS_DATA_CHECK(row->step(), location() << ": the atlas row is missing");
  vocabulary_hash_ = row->text(0);
  created_ns_ = row->int64(1);
}

int AtlasStore::schema_version() {
  if (auto* sqlite = dynamic_cast<SqliteDb*>(db_.get())) return read_schema_version(*sqlite);
  return read_postgres_schema_version(dynamic_cast<PgDb&>(*db_));
}

std::int64_t AtlasStore::checkpoint_sequence() {
  return db_->query_int64("SELECT checkpoint_seq FROM atlas WHERE id = 1");
}

std::vector<MapId> AtlasStore::stored_map_ids() {
  std::vector<MapId> ids;
  const std::unique_ptr<SqlStatement> rows = db_->prepare_statement("SELECT id FROM maps ORDER BY id");
  while (rows->step()) ids.push_back(id_column(*rows, 0));
  return ids;
}

}  // namespace orbatlas
