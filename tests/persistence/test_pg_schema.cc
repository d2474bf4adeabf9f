// The atlas's schema in PostgreSQL against SQLite's: the same tables
// and columns with the same types and nullability; the same rules (the
// one-map triggers, NaN refused where SQLite refuses it); migrations that
// apply once, and refuse another application's database. Skipped, with the
// reason, where PostgreSQL's binaries are missing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <mutex>
#include <thread>
#include <vector>

#include "core/common/error.h"
#include "core/persistence/pg_db.h"
#include "core/persistence/pg_schema.h"
#include "core/persistence/schema_migrations.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas {
namespace {

struct Column {
  std::string type;  // SQLite's declared type, or PostgreSQL's mapped to it
  bool not_null = false;
  bool operator==(const Column&) const = default;
};
using Schema = std::map<std::string, std::map<std::string, Column>>;  // table -> column -> Column

Schema sqlite_schema() {
  std::ostringstream file;
  file << "orbatlas_test_pg_schema_" << ::getpid() << ".db";
  const auto path = std::filesystem::temp_directory_path() / file.str();
  std::filesystem::remove(path);
  Schema schema;
  {
    SqliteDb db(path);
    migrate_schema(db, 1);
    SqliteStatement tables = db.prepare("SELECT name FROM sqlite_schema WHERE type = 'table' ORDER BY name");
    while (tables.step()) {
      const std::string table = tables.text(0);
      SqliteStatement columns = db.prepare("SELECT name, type, \"notnull\", pk FROM pragma_table_info(?1)");
      columns.bind_text(1, table);
      while (columns.step())
        // A primary key column is NOT NULL in PostgreSQL (and in a WITHOUT ROWID table).
        schema[table][columns.text(0)] = {columns.text(1), columns.int64(2) != 0 || columns.int64(3) != 0};
    }
  }
  std::filesystem::remove(path);
  return schema;
}

Schema postgres_schema(PgDb& db) {
  const std::map<std::string, std::string> as_sqlite = {
      {"bigint", "INTEGER"}, {"double precision", "REAL"}, {"text", "TEXT"}, {"bytea", "BLOB"}};
  Schema schema;
  PgStatement columns = db.prepare(
      "SELECT table_name::text, column_name::text, data_type::text, is_nullable::text FROM "
      "information_schema.columns WHERE table_schema = current_schema()");
  while (columns.step()) {
    const auto type = as_sqlite.find(columns.text(2));
    schema[columns.text(0)][columns.text(1)] = {type == as_sqlite.end() ? columns.text(2) : type->second,
                                                columns.text(3) == "NO"};
  }
  return schema;
}

using PgSchemaTest = test::PostgresDatabaseTest;

TEST_F(PgSchemaTest, TheTablesAndColumnsAreSqlitesInPostgresqlsDialect) {
  EXPECT_EQ(read_postgres_schema_version(*db_), 0);
  migrate_postgres_schema(*db_, 42);
  EXPECT_EQ(read_postgres_schema_version(*db_), latest_postgres_schema_version());
  migrate_postgres_schema(*db_, 43);  // nothing left to apply
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM schema_migrations"), latest_postgres_schema_version());
  EXPECT_EQ(db_->query_int64("SELECT applied_ns FROM schema_migrations WHERE version = 1"), 42);

  const Schema sqlite = sqlite_schema(), postgres = postgres_schema(*db_);
  std::set<std::string> sqlite_tables, postgres_tables;
  for (const auto& [t, c] : sqlite) sqlite_tables.insert(t);
  // PostgreSQL's only: atlas_writer (SQLite keeps the writer's record in its
  // lock file), replicas, map_owners, shared_jobs, shared_merges and
  // shared_session_work (an SQLite atlas has one server).
  const std::set<std::string> postgres_only = {"atlas_writer", "replicas",      "map_owners",
                                               "shared_jobs",  "shared_merges", "shared_session_work"};
  for (const auto& [t, c] : postgres)
    if (!postgres_only.count(t)) postgres_tables.insert(t);
  EXPECT_GE(sqlite_tables.size(), 16u);  // atlas, maps, keyframes, ... upload_jobs, keyframe_imu_states
  ASSERT_EQ(postgres_tables, sqlite_tables);
  for (const auto& [table, columns] : sqlite) {
    const auto& pg = postgres.at(table);
    for (const auto& [name, column] : columns) {
      ASSERT_TRUE(pg.count(name)) << table << "." << name << " is missing";
      EXPECT_EQ(pg.at(name).type, column.type) << table << "." << name;
      EXPECT_EQ(pg.at(name).not_null, column.not_null) << table << "." << name;
    }
    EXPECT_EQ(pg.size(), columns.size()) << table;
  }
}

TEST_F(PgSchemaTest, TheRulesHoldAsInSqlite) {
  migrate_postgres_schema(*db_, 1);
  db_->exec("INSERT INTO maps(id, saved_ns) VALUES (0, 1), (1, 1)");
  const auto keyframe = [&](std::int64_t id, std::int64_t map) {
    db_->prepare(
           "INSERT INTO keyframes(id, map_id, timestamp_ns, qw, qx, qy, qz, tx, ty, tz, c_qw, c_qx, c_qy, c_qz, c_tx, "
           "c_ty, c_tz, slot_count, features) VALUES (?1, ?2, 0, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 4, ?3)")
        .bind_int64(1, id)
        .bind_int64(2, map)
        .bind_blob(3, "f")
        .run();
  };
  keyframe(10, 0);
  keyframe(11, 0);
  keyframe(20, 1);
  db_->exec("INSERT INTO covisibility(keyframe_id, other_id, weight) VALUES (10, 11, 5)");
  try {
    db_->exec("INSERT INTO covisibility(keyframe_id, other_id, weight) VALUES (10, 20, 5)");
    FAIL() << "covisibility across maps was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("covisibility: keyframes in different maps"), std::string::npos) << e.what();
  }
  EXPECT_THROW(db_->exec("INSERT INTO loop_edges(keyframe_id, other_id) VALUES (10, 20)"), Error);
  db_->exec("INSERT INTO loop_edges(keyframe_id, other_id) VALUES (10, 11)");
  EXPECT_THROW(db_->exec("INSERT INTO culled_keyframes(id, map_id, qw, qx, qy, qz, tx, ty, tz) "
                         "VALUES (10, 0, 1, 0, 0, 0, 0, 0, 0)"),
               Error);  // alive
  db_->exec("INSERT INTO culled_keyframes(id, map_id, qw, qx, qy, qz, tx, ty, tz) VALUES (12, 0, 1, 0, 0, 0, 0, 0, 0)");
  EXPECT_THROW(keyframe(12, 0), Error);  // culled
  // NaN where SQLite's NOT NULL refuses it; a quaternion off the unit sphere.
  EXPECT_THROW(db_->prepare("INSERT INTO map_points(id, map_id, x, y, z, nx, ny, nz, min_distance, max_distance, "
                            "descriptor, visible, found) VALUES (1, 0, ?1, 0, 0, 0, 0, 1, 0, 1, ?2, 1, 1)")
                   .bind_real(1, std::nan(""))
                   .bind_blob(2, std::string(32, '\0'))
                   .run(),
               Error);
  EXPECT_THROW(db_->exec("INSERT INTO culled_keyframes(id, map_id, qw, qx, qy, qz, tx, ty, tz) "
                         "VALUES (13, 0, 2, 0, 0, 0, 0, 0, 0)"),
               Error);
}

TEST_F(PgSchemaTest, AnotherApplicationsDatabaseIsRefused) {
  db_->exec("CREATE TABLE invoices (id bigint)");
  EXPECT_THROW(migrate_postgres_schema(*db_, 1), DataError);
  EXPECT_EQ(read_postgres_schema_version(*db_), 0);
}

// One list for both databases: the same steps under the same numbers, each with
// a script for at least one of them.
TEST(SchemaList, BothDatabasesHaveTheSameNumberedSteps) {
  const auto sqlite = schema_migrations();
  const auto postgres = postgres_schema_migrations();
  ASSERT_EQ(sqlite.size(), postgres.size());
  for (std::size_t i = 0; i < sqlite.size(); ++i) {
    EXPECT_EQ(sqlite[i].version, static_cast<int>(i) + 1);
    EXPECT_EQ(postgres[i].version, sqlite[i].version);
    EXPECT_EQ(postgres[i].name, sqlite[i].name);
    EXPECT_FALSE(sqlite[i].sql.empty() && postgres[i].sql.empty()) << sqlite[i].name << " is empty on both";
  }
  EXPECT_EQ(latest_schema_version(), latest_postgres_schema_version());
}

// A database migrated while PostgreSQL had a list of its own (001 SQLite's
// schema 8, 002-008 the replica tables) is renumbered, then migrated on: the
// same tables and rows as a fresh one.
TEST_F(PgSchemaTest, ADatabaseOfTheSeparateListIsRenumberedAndMigratedOn) {
  migrate_postgres_schema(*db_, 1);
  // Back to what the separate list left: its rows 1..8, no session_records, no
  // scale-factor columns in map_inertial_states.
  db_->exec(
      "BEGIN; DROP TABLE session_records; ALTER TABLE map_inertial_states DROP COLUMN sgx, DROP COLUMN sgy, DROP "
      "COLUMN sgz, DROP COLUMN sax, DROP COLUMN say, DROP COLUMN saz; DELETE FROM schema_migrations WHERE version "
      "BETWEEN 2 AND 8 OR version "
      ">= 16; UPDATE schema_migrations SET name = '001_initial.sql' WHERE version = 1; UPDATE schema_migrations SET "
      "version = version - 7, name = CASE version WHEN 9 THEN '002_atlas_writer.sql' WHEN 10 THEN "
      "'003_replicas.sql' WHEN 11 THEN '004_map_owners.sql' WHEN 12 THEN '005_shared_jobs.sql' WHEN 13 THEN "
      "'006_shared_merges.sql' WHEN 14 THEN '007_merge_claims.sql' ELSE '008_session_merge_work.sql' END WHERE "
      "version BETWEEN 9 AND 15; COMMIT");
  ASSERT_EQ(read_postgres_schema_version(*db_), 8);
  migrate_postgres_schema(*db_, 2);
  EXPECT_EQ(read_postgres_schema_version(*db_), latest_postgres_schema_version());
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM schema_migrations"), latest_postgres_schema_version());
  const auto steps = postgres_schema_migrations();
  for (const SchemaMigration& step : steps) {
    PgStatement row = db_->prepare("SELECT name FROM schema_migrations WHERE version = ?1");
    row.bind_int64(1, step.version);
    ASSERT_TRUE(row.step()) << step.name;
    EXPECT_EQ(row.text(0), step.name);
  }
  EXPECT_EQ(db_->query_int64("SELECT to_regclass('session_records') IS NOT NULL"), 1);
  // Migrating again changes nothing.
  migrate_postgres_schema(*db_, 3);
  EXPECT_EQ(db_->query_int64("SELECT count(*) FROM schema_migrations"), latest_postgres_schema_version());
}

TEST_F(PgSchemaTest, ANewerSchemaIsRefused) {
  migrate_postgres_schema(*db_, 1);
  db_->prepare("INSERT INTO schema_migrations(version, name, applied_ns) VALUES (?1, 'future.sql', 1)")
      .bind_int64(1, latest_postgres_schema_version() + 1)
      .run();
  EXPECT_THROW(check_postgres_schema_supported(*db_), DataError);
}

// Replicas starting together on an empty database: one migrates while the
// others check what the database holds. A check that read "no
// schema_migrations" and then "16 tables" (the first migration committed
// between its two statements) refused the atlas as another application's (a
// CI run of ServerProcess.TwoLiveReplicasMappingOnePlaceEndInOneMap). Each
// round migrates a fresh database while three connections check it over and
// over until it is migrated: no check may refuse it.
TEST_F(PgSchemaTest, AReplicaCheckingWhileAnotherMigratesNeverRefusesTheAtlas) {
  constexpr int kRounds = 10, kCheckers = 3;
  std::atomic<int> checks = 0, refusals = 0;
  std::string first_refusal;
  std::mutex mutex;
  for (int round = 0; round < kRounds; ++round) {
    const std::string name = name_ + "_together_" + std::to_string(round);
    cluster().create_database(name);
    std::atomic<bool> migrated = false;
    std::vector<std::thread> checkers;
    for (int c = 0; c < kCheckers; ++c)
      checkers.emplace_back([&] {
        PgDb db(cluster().conninfo(name));
        while (!migrated) {
          try {
            check_postgres_schema_supported(db);
          } catch (const DataError& e) {
            const std::lock_guard lock(mutex);
            if (refusals++ == 0) first_refusal = e.what();
          }
          ++checks;
        }
      });
    {
      PgDb db(cluster().conninfo(name));
      migrate_postgres_schema(db, 1);
    }
    migrated = true;
    for (std::thread& checker : checkers) checker.join();
  }
  EXPECT_GT(checks, kRounds * kCheckers);
  EXPECT_EQ(refusals, 0) << "of " << checks << " checks; the first: " << first_refusal;
}

}  // namespace
}  // namespace orbatlas
