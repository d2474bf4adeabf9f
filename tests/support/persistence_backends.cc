#include "tests/support/persistence_backends.h"

#include <sstream>

#include "core/persistence/pg_db.h"
#include "core/persistence/sqlite_db.h"
#include "tests/support/requirement.h"

namespace orbatlas::test {

std::unique_ptr<ThrowawayPostgres> AtlasBackendTest::cluster_;
std::string AtlasBackendTest::skip_reason_;
int AtlasBackendTest::databases_ = 0;

void AtlasBackendTest::TearDownTestSuite() {
  cluster_.reset();
  skip_reason_.clear();
}

void AtlasBackendTest::SetUp() {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::ostringstream name;  // (a chain of string + here makes GCC 12 warn falsely, -Wrestrict)
  name << info->test_suite_name() << "_" << info->name();
  std::string unique = name.str();
  for (char& c : unique)
    if (c == '/') c = '_';
  unique_ = unique;
  if (backend() == SqlDialect::kSqlite) {
    file_ = std::make_unique<TempDb>(unique);
    return;
  }
  if (!cluster_ && skip_reason_.empty()) cluster_ = ThrowawayPostgres::start(&skip_reason_);
  if (!cluster_) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << skip_reason_);
  std::ostringstream db;
  db << "atlas" << ++databases_;
  cluster_->create_database(db.str());
  conninfo_ = cluster_->conninfo(db.str());
  uri_ = cluster_->uri(db.str());
}

std::string AtlasBackendTest::location() const {
  return backend() == SqlDialect::kSqlite ? file_->path().string() : uri_;
}

std::string AtlasBackendTest::another_location(const std::string& name) {
  if (backend() == SqlDialect::kSqlite) {
    other_files_.push_back(std::make_unique<TempDb>(unique_ + "_" + name));
    return other_files_.back()->path().string();
  }
  std::ostringstream db;
  db << "atlas" << ++databases_;
  cluster_->create_database(db.str());
  return cluster_->uri(db.str());
}

AtlasStore AtlasBackendTest::open_store(const std::string& vocabulary_hash) const {
  if (backend() == SqlDialect::kSqlite) return AtlasStore::open(file_->path(), vocabulary_hash);
  return AtlasStore::open_postgres(conninfo_, vocabulary_hash);
}

std::unique_ptr<SqlConnection> AtlasBackendTest::raw_connection() const {
  if (backend() == SqlDialect::kSqlite) return std::make_unique<SqliteDb>(file_->path());
  return std::make_unique<PgDb>(conninfo_);
}

std::string backend_name(const ::testing::TestParamInfo<SqlDialect>& info) {
  return std::string(sql_dialect_name(info.param));
}

}  // namespace orbatlas::test
