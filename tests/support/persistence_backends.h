#pragma once
// The persistence tests' backends, COLMAP-style: one test body,
// instantiated once per database. A test derives its suite from
// AtlasBackendTest and instantiates it with ORBATLAS_PERSISTENCE_BACKENDS;
// each instance gets a database of its own: a temporary SQLite file, or a
// fresh database in a throwaway PostgreSQL cluster (started for the suite's
// first PostgreSQL test, stopped at its end; the test is skipped, with the
// reason, where PostgreSQL cannot run).
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "core/persistence/atlas_store.h"
#include "core/persistence/sql_connection.h"
#include "tests/persistence/test_persistence_random_atlas.h"
#include "tests/support/throwaway_postgres.h"

namespace orbatlas::test {

class AtlasBackendTest : public ::testing::TestWithParam<SqlDialect> {
 protected:
  static void TearDownTestSuite();
  void SetUp() override;

  SqlDialect backend() const { return GetParam(); }
  // A new connection to this test's database each call, as reopening the file.
  AtlasStore open_store(const std::string& vocabulary_hash) const;
  // Where it is, as AtlasStore::open, AtlasCheckpointer and `--db` take it:
  // the SQLite file's path or a postgresql:// URI.
  std::string location() const;
  // Another empty database of this test's backend (kept until the test ends).
  std::string another_location(const std::string& name);
  // A plain connection to it (no atlas checks, no migrations), to inspect or tamper.
  std::unique_ptr<SqlConnection> raw_connection() const;

 private:
  static std::unique_ptr<ThrowawayPostgres> cluster_;  // the suite's, once started
  static std::string skip_reason_;                     // why it did not start
  static int databases_;                               // created in the cluster so far

  std::unique_ptr<TempDb> file_;  // SQLite
  std::string conninfo_, uri_;    // PostgreSQL
  std::string unique_;            // the test's name, for further databases
  std::vector<std::unique_ptr<TempDb>> other_files_;
};

// "sqlite" / "postgresql": the instances' names.
std::string backend_name(const ::testing::TestParamInfo<SqlDialect>& info);

}  // namespace orbatlas::test

// Runs every TEST_P of `suite` on SQLite and on PostgreSQL.
#define ORBATLAS_PERSISTENCE_BACKENDS(suite)                                                                      \
  INSTANTIATE_TEST_SUITE_P(Backends, suite,                                                                       \
                           ::testing::Values(::orbatlas::SqlDialect::kSqlite, ::orbatlas::SqlDialect::kPostgres), \
                           ::orbatlas::test::backend_name)

// Runs every TEST_P of `suite` on SQLite only (what only an SQLite file has).
#define ORBATLAS_SQLITE_BACKEND_ONLY(suite)                                                     \
  INSTANTIATE_TEST_SUITE_P(Backends, suite, ::testing::Values(::orbatlas::SqlDialect::kSqlite), \
                           ::orbatlas::test::backend_name)
