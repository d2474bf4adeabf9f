#pragma once
// The storage interface of the atlas's row code: one SQL connection
// and its statements, whichever database is behind them. SqliteDb /
// SqliteStatement (sqlite_db.h) and PgDb / PgStatement (pg_db.h) implement it,
// so the code that writes and reads an atlas's rows runs on either. SQL is
// written once, with SQLite's `?NNN` parameters, in what both dialects accept;
// the few differences go through dialect() (sql_dialect.h).
//
// The contract both implementations keep (tests/test_persistence*.cc run on
// both): parameters are 1-based and an unbound one is NULL; columns are 0-based
// and the typed readers are strict (NULL, or a value of another type, throws
// DataError; real() also reads integers); doubles and blobs round-trip exactly;
// failures are Error / DataError naming the database. Inside a write
// transaction a statement's failure may be thrown later than its run() (PgDb
// batches a write transaction's statements, pg_db.h), at the latest by
// commit(); let the SqlTransaction roll back then (PostgreSQL has aborted the
// whole transaction and refuses to commit it). A connection is used by one
// thread at a time; a statement lives no longer than its connection.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "core/persistence/sql_dialect.h"

namespace orbatlas {

class SqlStatement {
 public:
  virtual ~SqlStatement() = default;

  virtual SqlStatement& bind_int64(int index, std::int64_t value) = 0;
  virtual SqlStatement& bind_real(int index, double value) = 0;
  virtual SqlStatement& bind_text(int index, std::string_view text) = 0;
  virtual SqlStatement& bind_blob(int index, std::string_view bytes) = 0;  // empty: a zero-length blob, not NULL
  virtual SqlStatement& bind_null(int index) = 0;

  // True when a row is available, false when the statement is done.
  virtual bool step() = 0;
  // Runs a statement that returns no row (INSERT, UPDATE, DELETE) to completion.
  virtual void run() = 0;
  // Ready to run again: the bindings are cleared (every parameter NULL).
  virtual void reset() = 0;

  virtual bool is_null(int column) const = 0;
  virtual std::int64_t int64(int column) const = 0;
  virtual double real(int column) const = 0;
  virtual std::string text(int column) const = 0;
  virtual std::string blob(int column) const = 0;

 protected:
  SqlStatement() = default;
  SqlStatement(SqlStatement&&) noexcept = default;
  SqlStatement& operator=(SqlStatement&&) noexcept = default;
};

enum class SqlTransactionMode {
  kRead,   // one consistent snapshot for every statement
  kWrite,  // writes; other writers wait (SQLite: the file's write lock; PostgreSQL: row locks)
};

class SqlConnection {
 public:
  virtual ~SqlConnection() = default;

  virtual SqlDialect dialect() const = 0;
  // The database, for messages: the SQLite file's path, or "postgresql host:port/db".
  virtual const std::string& description() const = 0;

  // One or more statements without parameters or results (a migration script).
  virtual void exec(std::string_view sql) = 0;
  virtual std::unique_ptr<SqlStatement> prepare_statement(std::string_view sql) = 0;
  // The single integer a query returns (e.g. "PRAGMA user_version"); Error
  // when it returns no row.
  std::int64_t query_int64(std::string_view sql);

  // BEGIN in the backend's form of `mode`; use SqlTransaction rather than this.
  virtual void begin_transaction(SqlTransactionMode mode) = 0;

 protected:
  SqlConnection() = default;
  SqlConnection(SqlConnection&&) noexcept = default;
  SqlConnection& operator=(SqlConnection&&) noexcept = default;
};

// BEGIN on construction; ROLLBACK on destruction unless commit() ran, so an
// exception leaves the database as it was.
class SqlTransaction {
 public:
  using Mode = SqlTransactionMode;
  explicit SqlTransaction(SqlConnection& db, Mode mode = Mode::kWrite);
  ~SqlTransaction();
  SqlTransaction(const SqlTransaction&) = delete;
  SqlTransaction& operator=(const SqlTransaction&) = delete;

  void commit();

 private:
  SqlConnection& db_;
  bool open_ = true;
};

}  // namespace orbatlas
