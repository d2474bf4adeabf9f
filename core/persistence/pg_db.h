#pragma once
// RAII over one PostgreSQL connection (libpq), its statements and transactions,
// implementing the storage interface (sql_connection.h) as sqlite_db.h does,
// so that the atlas's row code runs on either database. Every
// failure becomes an exception naming the server (host, port, database) and
// carrying PostgreSQL's message: Error for connection, constraint and syntax
// failures, DataError for a value of an unexpected type or NULL read by a
// typed reader, and for data the server reports corrupt (SQLSTATE class
// XX001/XX002). libpq-fe.h stays out of this header. A connection is used by
// one thread at a time.
//
// SQL is written as for SQLite: parameters `?NNN` (or bare `?`, numbered in
// order) become PostgreSQL's `$NNN`; nothing inside quotes is touched. Values
// travel in binary (integers as int8, reals as float8, blobs as bytea), so
// doubles and blobs round-trip exactly. A statement has as many parameters as
// its SQL numbers (the largest `?NNN`); those left unbound are NULL, as in SQLite.
//
// Statements are prepared on the server (PQprepare) the first time a
// connection runs a given SQL text with given parameter types, and executed
// from then on by name (PQexecPrepared): a statement made again with the same
// SQL (each checkpoint makes its AtlasRowWriter anew) reuses the server's
// plan. The connection keeps its prepared statements until it closes (one per
// distinct SQL text and types the program runs: a few dozen).
//
// Writes are batched inside a write transaction (SqlTransaction in kWrite
// mode, i.e. PgDb::begin_transaction(kWrite)): there, run() does not wait for
// the server. It queues the execution in libpq's pipeline mode and returns;
// the server executes the queued statements in order while the program sends
// more, and their replies are read later, so a checkpoint or a full save costs
// a round trip per batch instead of one per row. The replies are read
//   - before anything that needs the server's answer: a step() that reads
//     rows (it sees every queued write, as without batching), exec() (COMMIT
//     among others), changes(), the first use of a new SQL text or types (its
//     PQprepare), and flush();
//   - and every kPipelineBatch queued statements, the batch before the last
//     (memory stays bounded; the server never waits for the program to read).
// A queued statement's failure therefore surfaces later than its run(): as an
// Error / DataError naming the server and the statement's SQL, thrown by a
// later run(), step(), flush() or at the latest by the COMMIT, never lost.
// PostgreSQL has then aborted the whole transaction, which the SqlTransaction
// destructor rolls back (exec("ROLLBACK") reads what is still queued and
// ignores its errors); the connection stays usable. Outside a write
// transaction (autocommit, read transactions) every statement runs at once,
// as before. The environment variable ORBATLAS_PG_BATCHING=0 turns batching
// off for the connections opened after it is set (to measure or compare).
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/persistence/sql_connection.h"
#include "core/persistence/sql_dialect.h"

struct pg_conn;
struct pg_result;

namespace orbatlas {

// A connection's state its statements share (pg_db.cc): the libpq connection,
// the server-side prepared statements by SQL text and parameter types, and the
// queue of batched executions whose replies are not read yet.
struct PgConnectionState;

class PgStatement final : public SqlStatement {
 public:
  PgStatement(PgStatement&&) noexcept = default;
  PgStatement& operator=(PgStatement&&) noexcept = default;

  // Parameters are 1-based, as in SQLite; an index above the statement's
  // parameters throws Error (SQLite: SQLITE_RANGE).
  PgStatement& bind_int64(int index, std::int64_t value) override;
  PgStatement& bind_real(int index, double value) override;
  PgStatement& bind_text(int index, std::string_view text) override;
  PgStatement& bind_blob(int index, std::string_view bytes) override;  // empty: a zero-length bytea, not NULL
  PgStatement& bind_null(int index) override;

  // The first call runs the statement (after reading the replies of any
  // batched writes: a failure among them throws here); true while a row is available.
  bool step() override;
  // Runs a statement to completion, its rows discarded. In a write
  // transaction: queued (see above), its failure thrown later.
  void run() override;
  // Ready to run again: forgets the result; every parameter NULL again.
  void reset() override;
  // Rows changed by the last run (INSERT, UPDATE, DELETE) since reset(); after a
  // queued run, reads the batched replies first (so it may throw their failure).
  std::int64_t changes() const;

  // Columns are 0-based. Strict, as SqliteStatement: NULL or another type throws DataError.
  bool is_null(int column) const override;
  std::int64_t int64(int column) const override;  // int2, int4, int8
  double real(int column) const override;         // float4, float8, and integers
  std::string text(int column) const override;    // text, varchar, name
  std::string blob(int column) const override;    // bytea

 private:
  friend class PgDb;
  friend struct PgConnectionState;
  // What a statement's queued executions share with the connection's queue:
  // the SQL for messages, and the rows the last execution changed.
  struct Runs {
    std::string sql;
    std::int64_t changes = 0;
    int unread = 0;  // queued executions whose reply is not read yet
  };
  PgStatement(PgConnectionState* state, std::string sql, int parameter_count);
  // The server-side statement for the current parameter types, prepared on first use.
  const std::string& prepared_name(const std::vector<unsigned>& types);
  // Queues the execution in the connection's pipeline (in a write transaction).
  void queue();
  void check_row(int column) const;
  [[noreturn]] void fail_type(int column, const char* expected) const;
  struct Param {
    std::optional<std::string> bytes;  // binary form (numbers in network byte order); nullopt: NULL
    unsigned oid = 0;
  };

  PgConnectionState* state_ = nullptr;  // borrowed from the PgDb that prepared it
  pg_conn* conn_ = nullptr;             // likewise
  std::string description_;             // the server, for messages
  std::string sql_;
  std::shared_ptr<Runs> runs_;
  // Parameter `index` (1-based).
  Param& param(int index);

  std::vector<Param> params_;
  struct Clearer {
    void operator()(pg_result* result) const;
  };
  std::unique_ptr<pg_result, Clearer> result_;
  int row_ = -1;
  bool ran_ = false;
};

class PgDb final : public SqlConnection {
 public:
  // Connects with a libpq connection string (`host=/tmp/x port=5432
  // dbname=atlas user=orbatlas`) or URI (`postgresql://user@host/db`).
  explicit PgDb(const std::string& conninfo);
  PgDb(PgDb&&) noexcept = default;
  PgDb& operator=(PgDb&&) noexcept = default;

  SqlDialect dialect() const override { return SqlDialect::kPostgres; }
  // "postgresql host:port/database", for messages.
  const std::string& description() const override { return description_; }

  // One or more statements without parameters or results (a migration script).
  // Reads the batched writes' replies first and throws their failure, except
  // for "ROLLBACK", which then rolls back all the same.
  void exec(std::string_view sql) override;
  // Reads the replies of every batched write: throws the first failure among
  // them (the transaction is then aborted; roll it back). Nothing to do outside
  // a write transaction.
  void flush();
  // Statements queued and not read yet (0 outside a write transaction); for tests.
  int queued() const;
  PgStatement prepare(std::string_view sql);
  std::unique_ptr<SqlStatement> prepare_statement(std::string_view sql) override;
  // kRead: REPEATABLE READ, READ ONLY (one snapshot for every statement);
  // kWrite: READ COMMITTED (PostgreSQL's default; writers lock the rows they
  // touch), with run() batched until COMMIT or ROLLBACK.
  void begin_transaction(SqlTransactionMode mode) override;

  // Statements queued per pipeline sync; the replies of the batch before the
  // last are read when a batch is full.
  static constexpr int kPipelineBatch = 1000;

 private:
  struct Closer {
    void operator()(pg_conn* conn) const;
  };
  struct StateDeleter {
    void operator()(PgConnectionState* state) const;
  };
  std::unique_ptr<pg_conn, Closer> conn_;
  std::unique_ptr<PgConnectionState, StateDeleter> state_;  // never null; a stable address
  std::string description_;
};

// BEGIN (see PgDb::begin_transaction) on construction; ROLLBACK on destruction
// unless commit() ran.
using PgTransaction = SqlTransaction;

}  // namespace orbatlas
