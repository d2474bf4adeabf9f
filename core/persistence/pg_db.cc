#include "core/persistence/pg_db.h"

#include <endian.h>
#include <libpq-fe.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <unordered_map>

#include "core/common/error.h"
#include "core/persistence/atlas_location.h"

namespace orbatlas {
namespace {

// PostgreSQL's type OIDs (catalog/pg_type.h; stable across versions).
constexpr unsigned kBoolOid = 16, kByteaOid = 17, kNameOid = 19, kInt8Oid = 20, kInt2Oid = 21, kInt4Oid = 23,
                   kTextOid = 25, kFloat4Oid = 700, kFloat8Oid = 701, kBpcharOid = 1042, kVarcharOid = 1043;

std::string describe(const PGconn* conn) {
  const char* host = PQhost(conn);
  const char* port = PQport(conn);
  const char* db = PQdb(conn);
  return std::string("postgresql ") + (host ? host : "?") + ":" + (port ? port : "?") + "/" + (db ? db : "?");
}

std::string trimmed(const char* message) {
  std::string m = message ? message : "";
  while (!m.empty() && std::isspace(static_cast<unsigned char>(m.back()))) m.pop_back();
  return m;
}

// Corrupt data reported by the server is bad input; anything else an error.
std::exception_ptr result_error(const PGresult* result, const PGconn* conn, const std::string& context) {
  const char* state = result ? PQresultErrorField(result, PG_DIAG_SQLSTATE) : nullptr;
  const std::string detail = trimmed(result ? PQresultErrorMessage(result) : PQerrorMessage(conn));
  const std::string message = describe(conn) + ": " + context + ": " +
                              (detail.empty() ? trimmed(PQerrorMessage(conn)) : detail) +
                              (state ? std::string(" (SQLSTATE ") + state + ")" : "");
  if (state && (std::strcmp(state, "XX001") == 0 || std::strcmp(state, "XX002") == 0))
    return std::make_exception_ptr(DataError(message));
  return std::make_exception_ptr(Error(message));
}

[[noreturn]] void throw_result(const PGresult* result, const PGconn* conn, const std::string& context) {
  std::rethrow_exception(result_error(result, conn, context));
}

void throw_if(const std::exception_ptr& failure) {
  if (failure) std::rethrow_exception(failure);
}

// "ROLLBACK" (any case, spaces and a semicolon around it).
bool is_rollback(std::string_view sql) {
  while (!sql.empty() && (std::isspace(static_cast<unsigned char>(sql.back())) || sql.back() == ';'))
    sql.remove_suffix(1);
  while (!sql.empty() && std::isspace(static_cast<unsigned char>(sql.front()))) sql.remove_prefix(1);
  constexpr std::string_view kRollback = "rollback";
  if (sql.size() != kRollback.size()) return false;
  for (std::size_t i = 0; i < sql.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(sql[i])) != kRollback[i]) return false;
  return true;
}

std::int64_t command_tuples(PGresult* result) {
  const char* n = PQcmdTuples(result);
  return n && *n ? std::stoll(n) : 0;
}

// A statement's parameters as libpq takes them (every one in binary).
struct ParamArrays {
  std::vector<unsigned> oids;
  std::vector<const char*> values;
  std::vector<int> lengths;
  std::vector<int> formats;
};

void ignore_notice(void*, const char*) {}  // NOTICEs (e.g. "already exists, skipping") are not errors

std::uint64_t load_be64(const char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return be64toh(v);
}

}  // namespace

struct PgConnectionState {
  PGconn* conn = nullptr;  // owned by the PgDb
  std::string description;
  // Key: the parameter types' bytes, then the SQL text. Value: the statement's name on the server.
  std::unordered_map<std::string, std::string> names;
  bool batching = true;  // false: ORBATLAS_PG_BATCHING=0
  // Between BEGIN (kWrite) and the end of the transaction: run() queues.
  bool write_transaction = false;
  // In the pipeline, in order: a queued execution (its statement's Runs) or a
  // sync (nullptr), each until its reply is read.
  std::deque<std::shared_ptr<PgStatement::Runs>> queue;
  int unsynced = 0;            // executions queued after the last sync
  int syncs = 0;               // syncs in the queue
  std::exception_ptr failure;  // the first failure read from the queue, not thrown yet

  bool pipelined() const { return PQpipelineStatus(conn) != PQ_PIPELINE_OFF; }

  void record(const PGresult* result, const std::string& context) {
    if (!failure) failure = result_error(result, conn, context);
  }

  // The connection failed under the queue (its replies will not come): forget it.
  void broken() {
    for (const auto& runs : queue)
      if (runs) runs->unread = 0;
    queue.clear();
    unsynced = syncs = 0;
  }

  void sync() {
    if (PQpipelineSync(conn) != 1) {
      record(nullptr, "sending a batch of writes");
      broken();
      return;
    }
    queue.push_back(nullptr);
    ++syncs;
    unsynced = 0;
  }

  // Reads the reply of the oldest queued execution or sync.
  void read_front() {
    const std::shared_ptr<PgStatement::Runs> runs = std::move(queue.front());
    queue.pop_front();
    if (!runs) {
      --syncs;
      PGresult* result = PQgetResult(conn);
      const bool ok = result && PQresultStatus(result) == PGRES_PIPELINE_SYNC;
      if (!ok) record(result, "reading the replies of a batch of writes");
      PQclear(result);
      if (!ok) broken();  // out of step with the server: nothing more to read
      return;
    }
    --runs->unread;
    const auto context = [&] {
      return "executing \"" + runs->sql + "\" (batched in a write transaction; it is aborted)";
    };
    PGresult* result = PQgetResult(conn);
    if (!result) {
      record(nullptr, context());
      broken();
      return;
    }
    switch (PQresultStatus(result)) {
      case PGRES_COMMAND_OK:
      case PGRES_TUPLES_OK:
        runs->changes = command_tuples(result);
        break;
      case PGRES_PIPELINE_ABORTED:  // skipped after an earlier failure, which is the one reported
        break;
      default:
        record(result, context());
    }
    PQclear(result);
    while ((result = PQgetResult(conn)) != nullptr) {  // up to the NULL that ends this execution's replies
      if (PQresultStatus(result) == PGRES_FATAL_ERROR) record(result, context());
      PQclear(result);
    }
  }

  // Every reply read, pipeline mode left; the first failure among them (then cleared).
  std::exception_ptr drain() {
    if (pipelined()) {
      if (unsynced > 0) sync();
      while (!queue.empty()) read_front();
      if (PQexitPipelineMode(conn) != 1) record(nullptr, "leaving pipeline mode");
      unsynced = syncs = 0;
    }
    std::exception_ptr out = failure;
    failure = nullptr;
    return out;
  }

  // After an execution was queued: a sync every kPipelineBatch executions, and
  // the batch before the last read (its failure thrown here, the queue drained first).
  void queued_one() {
    if (++unsynced < PgDb::kPipelineBatch) return;
    sync();
    while (syncs > 1 && !queue.empty()) read_front();
    if (failure) throw_if(drain());
  }
};

// --- PgStatement ---

void PgStatement::Clearer::operator()(pg_result* result) const { PQclear(result); }

PgStatement::PgStatement(PgConnectionState* state, std::string sql, int parameter_count)
    : state_(state),
      conn_(state->conn),
      description_(state->description),
      sql_(std::move(sql)),
      runs_(std::make_shared<Runs>(Runs{sql_, 0, 0})),
      params_(static_cast<std::size_t>(parameter_count)) {}

PgStatement::Param& PgStatement::param(int index) {
  ORBATLAS_CHECK(index >= 1 && static_cast<std::size_t>(index) <= params_.size(),
                 description_ << ": parameter index " << index << " out of range (the statement has " << params_.size()
                              << ", numbered from 1; in \"" << sql_ << "\")");
  return params_[static_cast<std::size_t>(index - 1)];
}

PgStatement& PgStatement::bind_int64(int index, std::int64_t value) {
  const std::uint64_t be = htobe64(static_cast<std::uint64_t>(value));
  param(index) = {std::string(reinterpret_cast<const char*>(&be), 8), kInt8Oid};
  return *this;
}

PgStatement& PgStatement::bind_real(int index, double value) {
  std::uint64_t bits;
  std::memcpy(&bits, &value, 8);
  const std::uint64_t be = htobe64(bits);
  param(index) = {std::string(reinterpret_cast<const char*>(&be), 8), kFloat8Oid};
  return *this;
}

PgStatement& PgStatement::bind_text(int index, std::string_view text) {
  param(index) = {std::string(text), kTextOid};  // text's binary form: its bytes
  return *this;
}

PgStatement& PgStatement::bind_blob(int index, std::string_view bytes) {
  param(index) = {std::string(bytes), kByteaOid};
  return *this;
}

PgStatement& PgStatement::bind_null(int index) {
  param(index) = Param{};
  return *this;
}

const std::string& PgStatement::prepared_name(const std::vector<unsigned>& types) {
  // The types are part of the key: a parameter bound as int8 once and as NULL
  // (type left to the server) another time gets two statements, each with
  // exactly the types PQexecParams would have sent.
  std::string key(reinterpret_cast<const char*>(types.data()), types.size() * sizeof(unsigned));
  key += sql_;
  if (const auto it = state_->names.find(key); it != state_->names.end()) return it->second;
  // PQprepare waits for its reply: the batched writes' replies are read first
  // (a new SQL text or types in a write transaction: a few per connection).
  throw_if(state_->drain());
  std::string name = "orbatlas_" + std::to_string(state_->names.size() + 1);
  const std::unique_ptr<PGresult, decltype(&PQclear)> result(
      PQprepare(conn_, name.c_str(), sql_.c_str(), static_cast<int>(types.size()), types.data()), &PQclear);
  if (!result || PQresultStatus(result.get()) != PGRES_COMMAND_OK)
    throw_result(result.get(), conn_, "preparing \"" + sql_ + "\"");
  return state_->names.emplace(std::move(key), std::move(name)).first->second;
}

namespace {

template <class Params>  // PgStatement's
ParamArrays param_arrays(const Params& params) {
  ParamArrays a;
  for (const auto& p : params) {
    a.oids.push_back(p.oid);
    a.values.push_back(p.bytes ? p.bytes->data() : nullptr);
    a.lengths.push_back(p.bytes ? static_cast<int>(p.bytes->size()) : 0);
  }
  a.formats.assign(params.size(), 1);  // every parameter in binary
  return a;
}

}  // namespace

bool PgStatement::step() {
  if (!ran_) {
    throw_if(state_->drain());  // the batched writes first: this reads what they wrote
    const ParamArrays a = param_arrays(params_);
    const std::string& name = prepared_name(a.oids);
    result_.reset(PQexecPrepared(conn_, name.c_str(), static_cast<int>(params_.size()), a.values.data(),
                                 a.lengths.data(), a.formats.data(), 1));
    const ExecStatusType status = result_ ? PQresultStatus(result_.get()) : PGRES_FATAL_ERROR;
    if (status != PGRES_TUPLES_OK && status != PGRES_COMMAND_OK)
      throw_result(result_.get(), conn_, "executing \"" + sql_ + "\"");
    runs_->changes = command_tuples(result_.get());
    ran_ = true;
    row_ = -1;
  }
  ++row_;
  return row_ < PQntuples(result_.get());
}

void PgStatement::queue() {
  const ParamArrays a = param_arrays(params_);
  const std::string& name = prepared_name(a.oids);  // may read the queue (a new statement)
  if (!state_->pipelined() && PQenterPipelineMode(conn_) != 1) throw_result(nullptr, conn_, "entering pipeline mode");
  if (PQsendQueryPrepared(conn_, name.c_str(), static_cast<int>(params_.size()), a.values.data(), a.lengths.data(),
                          a.formats.data(), 1) != 1) {
    state_->record(nullptr, "sending \"" + sql_ + "\"");  // e.g. the connection is gone
    std::exception_ptr failure = state_->drain();
    std::rethrow_exception(failure);
  }
  ++runs_->unread;
  state_->queue.push_back(runs_);
  result_.reset();
  ran_ = true;  // no rows: step() returns false, as after a run
  row_ = -1;
  state_->queued_one();
}

void PgStatement::run() {
  if (!ran_ && state_->write_transaction) {
    queue();
    return;
  }
  while (step()) {
  }
}

void PgStatement::reset() {
  result_.reset();
  for (Param& p : params_) p = Param{};
  ran_ = false;
  row_ = -1;
}

std::int64_t PgStatement::changes() const {
  ORBATLAS_CHECK(ran_, description_ << ": changes() before the statement ran");
  if (runs_->unread > 0) throw_if(state_->drain());
  return runs_->changes;
}

void PgStatement::check_row(int column) const {
  ORBATLAS_CHECK(result_ && row_ >= 0 && row_ < PQntuples(result_.get()),
                 description_ << ": no current row (in \"" << sql_ << "\")");
  ORBATLAS_CHECK(column >= 0 && column < PQnfields(result_.get()),
                 description_ << ": no column " << column << " (in \"" << sql_ << "\")");
}

void PgStatement::fail_type(int column, const char* expected) const {
  const char* name = PQfname(result_.get(), column);
  throw DataError(description_ + ": column " + (name ? name : "?") + " holds " +
                  (PQgetisnull(result_.get(), row_, column) ? "NULL" : "a value of another type") + ", expected " +
                  expected + " (in \"" + sql_ + "\")");
}

bool PgStatement::is_null(int column) const {
  check_row(column);
  return PQgetisnull(result_.get(), row_, column) != 0;
}

std::int64_t PgStatement::int64(int column) const {
  check_row(column);
  if (PQgetisnull(result_.get(), row_, column)) fail_type(column, "an integer");
  const char* p = PQgetvalue(result_.get(), row_, column);
  switch (PQftype(result_.get(), column)) {
    case kInt8Oid:
      return static_cast<std::int64_t>(load_be64(p));
    case kInt4Oid: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return static_cast<std::int32_t>(be32toh(v));
    }
    case kInt2Oid: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return static_cast<std::int16_t>(be16toh(v));
    }
    case kBoolOid:
      return p[0] != 0 ? 1 : 0;
    default:
      fail_type(column, "an integer");
  }
}

double PgStatement::real(int column) const {
  check_row(column);
  if (PQgetisnull(result_.get(), row_, column)) fail_type(column, "a real");
  const char* p = PQgetvalue(result_.get(), row_, column);
  switch (PQftype(result_.get(), column)) {
    case kFloat8Oid: {
      const std::uint64_t bits = load_be64(p);
      double v;
      std::memcpy(&v, &bits, 8);
      return v;
    }
    case kFloat4Oid: {
      std::uint32_t bits;
      std::memcpy(&bits, p, 4);
      bits = be32toh(bits);
      float v;
      std::memcpy(&v, &bits, 4);
      return v;
    }
    case kInt8Oid:
    case kInt4Oid:
    case kInt2Oid:
      return static_cast<double>(int64(column));  // as SQLite: integers read as reals
    default:
      fail_type(column, "a real");
  }
}

std::string PgStatement::text(int column) const {
  check_row(column);
  const unsigned type = PQftype(result_.get(), column);
  if (PQgetisnull(result_.get(), row_, column) ||
      (type != kTextOid && type != kVarcharOid && type != kBpcharOid && type != kNameOid))
    fail_type(column, "text");
  return std::string(PQgetvalue(result_.get(), row_, column),
                     static_cast<std::size_t>(PQgetlength(result_.get(), row_, column)));
}

std::string PgStatement::blob(int column) const {
  check_row(column);
  if (PQgetisnull(result_.get(), row_, column) || PQftype(result_.get(), column) != kByteaOid)
    fail_type(column, "a blob");
  return std::string(PQgetvalue(result_.get(), row_, column),
                     static_cast<std::size_t>(PQgetlength(result_.get(), row_, column)));
}

// --- PgDb ---

void PgDb::Closer::operator()(pg_conn* conn) const { PQfinish(conn); }

void PgDb::StateDeleter::operator()(PgConnectionState* state) const { delete state; }

PgDb::PgDb(const std::string& conninfo) : conn_(PQconnectdb(conninfo.c_str())), state_(new PgConnectionState) {
  ORBATLAS_CHECK(conn_, "postgresql: cannot connect: out of memory");
  if (PQstatus(conn_.get()) != CONNECTION_OK)
    throw Error("postgresql: cannot connect" +
                (is_postgres_location(conninfo) ? " to " + location_for_messages(conninfo) : std::string()) + " (" +
                trimmed(PQerrorMessage(conn_.get())) + ")");
  description_ = describe(conn_.get());
  state_->conn = conn_.get();
  state_->description = description_;
  const char* batching = std::getenv("ORBATLAS_PG_BATCHING");  // "0": one round trip per statement, to compare
  state_->batching = !(batching && std::strcmp(batching, "0") == 0);
  PQsetNoticeProcessor(conn_.get(), ignore_notice, nullptr);
}

void PgDb::exec(std::string_view sql) {
  // The batched writes' replies first. After a failure among them the
  // transaction is aborted: thrown, except to a ROLLBACK, which ends it.
  const std::exception_ptr failure = state_->drain();
  if (failure && !is_rollback(sql)) std::rethrow_exception(failure);
  const bool failed_before = PQtransactionStatus(conn_.get()) == PQTRANS_INERROR;
  const std::string text(sql);
  std::unique_ptr<PGresult, decltype(&PQclear)> result(PQexec(conn_.get(), text.c_str()), &PQclear);
  if (PQtransactionStatus(conn_.get()) == PQTRANS_IDLE) state_->write_transaction = false;  // COMMIT, ROLLBACK
  const ExecStatusType status = result ? PQresultStatus(result.get()) : PGRES_FATAL_ERROR;
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK && status != PGRES_EMPTY_QUERY)
    throw_result(result.get(), conn_.get(), "executing SQL");
  // PostgreSQL answers COMMIT in a failed transaction with ROLLBACK, and no
  // error: an error here, as SQLite's COMMIT never drops rows silently.
  if (failed_before && !is_rollback(sql) && std::strcmp(PQcmdStatus(result.get()), "ROLLBACK") == 0)
    throw Error(description_ + ": \"" + text +
                "\" rolled the transaction back: a statement in it had failed (its error was thrown earlier)");
}

void PgDb::flush() { throw_if(state_->drain()); }

int PgDb::queued() const { return static_cast<int>(state_->queue.size()) - state_->syncs; }

PgStatement PgDb::prepare(std::string_view sql) {
  int parameters = 0;
  std::string translated = sqlite_params_to_postgres(sql, &parameters);
  return PgStatement(state_.get(), std::move(translated), parameters);
}

std::unique_ptr<SqlStatement> PgDb::prepare_statement(std::string_view sql) {
  return std::make_unique<PgStatement>(prepare(sql));
}

void PgDb::begin_transaction(SqlTransactionMode mode) {
  exec(mode == SqlTransactionMode::kRead ? "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY" : "BEGIN");
  state_->write_transaction = mode == SqlTransactionMode::kWrite && state_->batching;
}

}  // namespace orbatlas
