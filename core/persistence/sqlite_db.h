#pragma once
// RAII over one SQLite connection, its prepared statements and transactions.
// Every failure becomes an exception naming the database file and carrying
// SQLite's message: DataError when the file is not a database or is corrupt,
// Error otherwise (constraint violations, I/O, busy). sqlite3.h stays out of
// this header. A connection is used by one thread at a time.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

struct sqlite3;
struct sqlite3_stmt;

namespace orbatlas {

class SqliteStatement {
 public:
  SqliteStatement(SqliteStatement&&) noexcept = default;
  SqliteStatement& operator=(SqliteStatement&&) noexcept = default;

  // Parameters are 1-based, as in SQLite. Text and blobs are copied by SQLite.
  SqliteStatement& bind_int64(int index, std::int64_t value);
  SqliteStatement& bind_real(int index, double value);
  SqliteStatement& bind_text(int index, std::string_view text);
  SqliteStatement& bind_blob(int index, std::string_view bytes);  // empty binds a zero-length blob, not NULL
  SqliteStatement& bind_null(int index);

  // True when a row is available, false when the statement is done.
  bool step();
  // Runs a statement that returns no row (INSERT, UPDATE, DELETE) to completion.
  void run();
  // Ready to run again: resets and clears the bindings.
  void reset();

  // Columns are 0-based. The typed readers are strict: a stored value of another
  // type (e.g. TEXT where an INTEGER belongs) throws DataError, as does NULL.
  bool is_null(int column) const;
  std::int64_t int64(int column) const;
  double real(int column) const;  // INTEGER values are accepted and converted
  std::string text(int column) const;
  std::string blob(int column) const;

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

class SqliteDb {
 public:
  // Opens the file read-write, creating an empty one when missing. Nothing is
  // read yet: a file that is not an SQLite database is only noticed (DataError)
  // by the first statement.
  explicit SqliteDb(const std::filesystem::path& path);
  SqliteDb(SqliteDb&&) noexcept = default;
  SqliteDb& operator=(SqliteDb&&) noexcept = default;

  // One or more statements without results (a migration script).
  void exec(std::string_view sql);
  SqliteStatement prepare(std::string_view sql);
  // The single integer a query returns (e.g. "PRAGMA user_version").
  std::int64_t query_int64(std::string_view sql);

  const std::filesystem::path& path() const { return path_; }

 private:
  struct Closer {
    void operator()(sqlite3* db) const;
  };
  [[noreturn]] void fail(int rc, std::string_view context) const;

  std::filesystem::path path_;
  std::unique_ptr<sqlite3, Closer> db_;  // the owning handle
};

// BEGIN on construction; ROLLBACK on destruction unless commit() ran, so an
// exception leaves the database as it was.
class SqliteTransaction {
 public:
  enum class Mode {
    kRead,   // BEGIN DEFERRED: a consistent snapshot for reading
    kWrite,  // BEGIN IMMEDIATE: takes the write lock at once (no upgrade deadlock)
  };
  explicit SqliteTransaction(SqliteDb& db, Mode mode = Mode::kWrite);
  ~SqliteTransaction();
  SqliteTransaction(const SqliteTransaction&) = delete;
  SqliteTransaction& operator=(const SqliteTransaction&) = delete;

  void commit();

 private:
  SqliteDb& db_;
  bool open_ = true;
};

}  // namespace orbatlas
