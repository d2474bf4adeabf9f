#pragma once
// RAII over one SQLite connection, its prepared statements and transactions.
// Every failure becomes an exception naming the database file and carrying
// SQLite's message: DataError when the file is not a database or is corrupt,
// Error otherwise (constraint violations, I/O, busy). sqlite3.h stays out of
// this header. A connection is used by one thread at a time. Implements the
// storage interface (sql_connection.h) that the atlas's row code is written to.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "core/persistence/sql_connection.h"

struct sqlite3;
struct sqlite3_stmt;

namespace orbatlas {

class SqliteStatement final : public SqlStatement {
 public:
  SqliteStatement(SqliteStatement&&) noexcept = default;
  SqliteStatement& operator=(SqliteStatement&&) noexcept = default;

  // Parameters are 1-based, as in SQLite. Text and blobs are copied by SQLite.
  SqliteStatement& bind_int64(int index, std::int64_t value) override;
  SqliteStatement& bind_real(int index, double value) override;
  SqliteStatement& bind_text(int index, std::string_view text) override;
  SqliteStatement& bind_blob(int index, std::string_view bytes) override;  // empty: a zero-length blob, not NULL
  SqliteStatement& bind_null(int index) override;

  // True when a row is available, false when the statement is done.
  bool step() override;
  // Runs a statement that returns no row (INSERT, UPDATE, DELETE) to completion.
  void run() override;
  // Ready to run again: resets and clears the bindings.
  void reset() override;

  // Columns are 0-based. The typed readers are strict: a stored value of another
  // type (e.g. TEXT where an INTEGER belongs) throws DataError, as does NULL.
  bool is_null(int column) const override;
  std::int64_t int64(int column) const override;
  double real(int column) const override;  // INTEGER values are accepted and converted
  std::string text(int column) const override;
  std::string blob(int column) const override;

 private:
  friend class SqliteDb;
  struct Finalizer {
    void operator()(sqlite3_stmt* stmt) const;
  };
  explicit SqliteStatement(sqlite3_stmt* stmt) : stmt_(stmt) {}
  void check_bind(int rc, int index) const;
  void check_type(int column, int expected, const char* expected_name) const;
  [[noreturn]] void fail(int rc, std::string_view context) const;

  std::unique_ptr<sqlite3_stmt, Finalizer> stmt_;
};

class SqliteDb final : public SqlConnection {
 public:
  // Opens the file read-write, creating an empty one when missing. Nothing is
  // read yet: a file that is not an SQLite database is only noticed (DataError)
  // by the first statement.
  explicit SqliteDb(const std::filesystem::path& path);
  SqliteDb(SqliteDb&&) noexcept = default;
  SqliteDb& operator=(SqliteDb&&) noexcept = default;

  SqlDialect dialect() const override { return SqlDialect::kSqlite; }
  const std::string& description() const override { return description_; }  // the path

  // One or more statements without results (a migration script).
  void exec(std::string_view sql) override;
  SqliteStatement prepare(std::string_view sql);
  std::unique_ptr<SqlStatement> prepare_statement(std::string_view sql) override;
  // kRead: BEGIN DEFERRED (a consistent snapshot for reading); kWrite: BEGIN
  // IMMEDIATE (takes the write lock at once: no upgrade deadlock).
  void begin_transaction(SqlTransactionMode mode) override;

  const std::filesystem::path& path() const { return path_; }

 private:
  struct Closer {
    void operator()(sqlite3* db) const;
  };
  [[noreturn]] void fail(int rc, std::string_view context) const;

  std::filesystem::path path_;
  std::string description_;
  std::unique_ptr<sqlite3, Closer> db_;  // the owning handle
};

// BEGIN (DEFERRED for kRead, IMMEDIATE for kWrite) on construction; ROLLBACK on
// destruction unless commit() ran.
using SqliteTransaction = SqlTransaction;

}  // namespace orbatlas
