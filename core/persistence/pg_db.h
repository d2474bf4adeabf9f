#pragma once
// RAII over one PostgreSQL connection (libpq), its statements and transactions,
// with the same shape as sqlite_db.h so that the atlas's row code can run on
// either database (issue 23). Every failure becomes an exception naming the
// server (host, port, database) and carrying PostgreSQL's message: Error for
// connection, constraint and syntax failures, DataError for a value of an
// unexpected type or NULL read by a typed reader, and for data the server
// reports corrupt (SQLSTATE class XX001/XX002). libpq-fe.h stays out of this
// header. A connection is used by one thread at a time.
//
// SQL is written as for SQLite: parameters `?NNN` (or bare `?`, numbered in
// order) become PostgreSQL's `$NNN`; nothing inside quotes is touched. Values
// travel in binary (integers as int8, reals as float8, blobs as bytea), so
// doubles and blobs round-trip exactly.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

struct pg_conn;
struct pg_result;

namespace orbatlas {

// `?NNN` and `?` -> `$NNN` outside quoted strings and identifiers (tested).
std::string sqlite_params_to_postgres(std::string_view sql);

class PgStatement {
 public:
  PgStatement(PgStatement&&) noexcept = default;
  PgStatement& operator=(PgStatement&&) noexcept = default;

  // Parameters are 1-based, as in SQLite.
  PgStatement& bind_int64(int index, std::int64_t value);
  PgStatement& bind_real(int index, double value);
  PgStatement& bind_text(int index, std::string_view text);
  PgStatement& bind_blob(int index, std::string_view bytes);  // empty binds a zero-length bytea, not NULL
  PgStatement& bind_null(int index);

  // The first call runs the statement; true while a row is available.
  bool step();
  // Runs a statement that returns no row to completion.
  void run();
  // Ready to run again: forgets the result and the bindings.
  void reset();
  // Rows changed by the last run (INSERT, UPDATE, DELETE).
  std::int64_t changes() const;

  // Columns are 0-based. Strict, as SqliteStatement: NULL or another type throws DataError.
  bool is_null(int column) const;
  std::int64_t int64(int column) const;  // int2, int4, int8
  double real(int column) const;         // float4, float8, and integers
  std::string text(int column) const;    // text, varchar, name
  std::string blob(int column) const;    // bytea

 private:
  friend class PgDb;
  PgStatement(pg_conn* conn, std::string description, std::string sql);
  void check_row(int column) const;
  [[noreturn]] void fail_type(int column, const char* expected) const;
  struct Param {
    std::optional<std::string> bytes;  // binary form (numbers in network byte order); nullopt: NULL
    unsigned oid = 0;
  };

  pg_conn* conn_ = nullptr;  // borrowed from the PgDb that prepared it
  std::string description_;  // the server, for messages
  std::string sql_;
  // Parameter `index` (1-based), the ones before it NULL until bound.
  Param& param(int index);

  std::vector<Param> params_;
  struct Clearer {
    void operator()(pg_result* result) const;
  };
  std::unique_ptr<pg_result, Clearer> result_;
  int row_ = -1;
  bool ran_ = false;
};

class PgDb {
 public:
  // Connects with a libpq connection string (`host=/tmp/x port=5432
  // dbname=atlas user=orbatlas`) or URI (`postgresql://user@host/db`).
  explicit PgDb(const std::string& conninfo);
  PgDb(PgDb&&) noexcept = default;
  PgDb& operator=(PgDb&&) noexcept = default;

  // One or more statements without parameters or results (a migration script).
  void exec(std::string_view sql);
  PgStatement prepare(std::string_view sql);
  // The single integer a query returns.
  std::int64_t query_int64(std::string_view sql);

  // host:port/database, for messages.
  const std::string& description() const { return description_; }

 private:
  struct Closer {
    void operator()(pg_conn* conn) const;
  };
  std::unique_ptr<pg_conn, Closer> conn_;
  std::string description_;
};

// BEGIN on construction; ROLLBACK on destruction unless commit() ran.
class PgTransaction {
 public:
  enum class Mode {
    kRead,   // REPEATABLE READ, READ ONLY: one snapshot for every statement
    kWrite,  // READ COMMITTED (PostgreSQL's default); writers lock the rows they touch
  };
  explicit PgTransaction(PgDb& db, Mode mode = Mode::kWrite);
  ~PgTransaction();
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;

  void commit();

 private:
  PgDb& db_;
  bool open_ = true;
};

}  // namespace orbatlas
