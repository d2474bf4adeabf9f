#pragma once
// A throwaway PostgreSQL cluster for tests: initdb into a temporary
// folder, the server listening on a Unix socket in that folder only (no TCP
// port, so parallel tests never collide), stopped and removed at the end. The
// binaries are Debian's (`postgresql`, installed by scripts/setup.sh); as root,
// initdb and the server run as the `postgres` user, since PostgreSQL refuses
// to run as root.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>

#include "core/persistence/pg_db.h"

namespace orbatlas::test {

class ThrowawayPostgres {
 public:
  // nullptr, with the reason in *why_not, when PostgreSQL's binaries are missing
  // or the cluster does not start (tests skip with that message).
  static std::unique_ptr<ThrowawayPostgres> start(std::string* why_not);
  ~ThrowawayPostgres();
  ThrowawayPostgres(const ThrowawayPostgres&) = delete;
  ThrowawayPostgres& operator=(const ThrowawayPostgres&) = delete;

  // A libpq connection string for database `db` as the cluster's superuser.
  std::string conninfo(const std::string& db = "postgres") const;
  // The same as a postgresql:// URI, as `--db` and AtlasStore::open take it.
  std::string uri(const std::string& db = "postgres") const;
  // CREATE DATABASE name (a fresh database per test).
  void create_database(const std::string& name);
  const std::filesystem::path& folder() const { return dir_; }

 private:
  ThrowawayPostgres(std::filesystem::path dir, std::filesystem::path bin, bool as_postgres)
      : dir_(std::move(dir)), bin_(std::move(bin)), as_postgres_(as_postgres) {}
  // Runs a PostgreSQL binary (as `postgres` when we are root); its exit status.
  int run(const std::string& binary, const std::string& args, const std::string& log) const;

  std::filesystem::path dir_, bin_;
  bool as_postgres_ = false;
  bool running_ = false;
};

// A test with a fresh database of its own (db_, named name_) in a cluster that
// the test suite starts once and stops at its end; skipped, with the reason,
// where PostgreSQL cannot run.
class PostgresDatabaseTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite();
  static void TearDownTestSuite();
  void SetUp() override;

  static ThrowawayPostgres& cluster() { return *cluster_; }
  std::string name_;
  std::unique_ptr<PgDb> db_;

 private:
  static std::unique_ptr<ThrowawayPostgres> cluster_;
  static std::string skip_reason_;
};

}  // namespace orbatlas::test
