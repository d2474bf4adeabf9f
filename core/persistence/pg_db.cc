#include "core/persistence/pg_db.h"

#include <endian.h>
#include <libpq-fe.h>

#include <cctype>
#include <cstring>
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
[[noreturn]] void throw_result(const PGresult* result, const PGconn* conn, const std::string& context) {
  const char* state = result ? PQresultErrorField(result, PG_DIAG_SQLSTATE) : nullptr;
  const std::string detail = trimmed(result ? PQresultErrorMessage(result) : PQerrorMessage(conn));
  const std::string message = describe(conn) + ": " + context + ": " +
                              (detail.empty() ? trimmed(PQerrorMessage(conn)) : detail) +
                              (state ? std::string(" (SQLSTATE ") + state + ")" : "");
  if (state && (std::strcmp(state, "XX001") == 0 || std::strcmp(state, "XX002") == 0)) throw DataError(message);
  throw Error(message);
}

void ignore_notice(void*, const char*) {}  // NOTICEs (e.g. "already exists, skipping") are not errors

std::uint64_t load_be64(const char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return be64toh(v);
}

}  // namespace

std::string sqlite_params_to_postgres(std::string_view sql, int* parameter_count) {
  std::string out;
  out.reserve(sql.size() + 8);
  long next = 0;  // a bare '?' is one more than the largest number so far, as in SQLite
  char quote = 0;
  for (std::size_t i = 0; i < sql.size(); ++i) {
    const char c = sql[i];
    if (quote != 0) {
      out += c;
      if (c == quote) quote = 0;  // a doubled quote closes and reopens: the same text
      continue;
    }
    if (c == '\'' || c == '"') {
      quote = c;
      out += c;
      continue;
    }
    if (c != '?') {
      out += c;
      continue;
    }
    std::size_t j = i + 1;
    while (j < sql.size() && std::isdigit(static_cast<unsigned char>(sql[j]))) ++j;
    if (j > i + 1) {
      const std::string digits(sql.substr(i + 1, j - i - 1));
      next = std::max(next, std::stol(digits));
      out += '$';
      out += digits;
      i = j - 1;
    } else {
      out += '$';
      out += std::to_string(++next);
    }
  }
  if (parameter_count) *parameter_count = static_cast<int>(next);
  return out;
}

struct PgPreparedStatements {
  // Key: the parameter types' bytes, then the SQL text. Value: the statement's name on the server.
  std::unordered_map<std::string, std::string> names;
};

// --- PgStatement ---

void PgStatement::Clearer::operator()(pg_result* result) const { PQclear(result); }

PgStatement::PgStatement(pg_conn* conn, PgPreparedStatements* prepared, std::string description, std::string sql,
                         int parameter_count)
    : conn_(conn),
      prepared_(prepared),
      description_(std::move(description)),
      sql_(std::move(sql)),
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
  if (const auto it = prepared_->names.find(key); it != prepared_->names.end()) return it->second;
  std::string name = "orbatlas_" + std::to_string(prepared_->names.size() + 1);
  const std::unique_ptr<PGresult, decltype(&PQclear)> result(
      PQprepare(conn_, name.c_str(), sql_.c_str(), static_cast<int>(types.size()), types.data()), &PQclear);
  if (!result || PQresultStatus(result.get()) != PGRES_COMMAND_OK)
    throw_result(result.get(), conn_, "preparing \"" + sql_ + "\"");
  return prepared_->names.emplace(std::move(key), std::move(name)).first->second;
}

bool PgStatement::step() {
  if (!ran_) {
    std::vector<unsigned> oids;
    std::vector<const char*> values;
    std::vector<int> lengths;
    for (const Param& p : params_) {
      oids.push_back(p.oid);
      values.push_back(p.bytes ? p.bytes->data() : nullptr);
      lengths.push_back(p.bytes ? static_cast<int>(p.bytes->size()) : 0);
    }
    const std::vector<int> formats(params_.size(), 1);  // every parameter in binary
    const std::string& name = prepared_name(oids);
    result_.reset(PQexecPrepared(conn_, name.c_str(), static_cast<int>(params_.size()), values.data(), lengths.data(),
                                 formats.data(), 1));
    const ExecStatusType status = result_ ? PQresultStatus(result_.get()) : PGRES_FATAL_ERROR;
    if (status != PGRES_TUPLES_OK && status != PGRES_COMMAND_OK)
      throw_result(result_.get(), conn_, "executing \"" + sql_ + "\"");
    ran_ = true;
    row_ = -1;
  }
  ++row_;
  return row_ < PQntuples(result_.get());
}

void PgStatement::run() {
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
  ORBATLAS_CHECK(result_, description_ << ": changes() before the statement ran");
  const char* n = PQcmdTuples(result_.get());
  return n && *n ? std::stoll(n) : 0;
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

void PgDb::PreparedDeleter::operator()(PgPreparedStatements* prepared) const { delete prepared; }

PgDb::PgDb(const std::string& conninfo) : conn_(PQconnectdb(conninfo.c_str())), prepared_(new PgPreparedStatements) {
  ORBATLAS_CHECK(conn_, "postgresql: cannot connect: out of memory");
  if (PQstatus(conn_.get()) != CONNECTION_OK)
    throw Error("postgresql: cannot connect" +
                (is_postgres_location(conninfo) ? " to " + location_for_messages(conninfo) : std::string()) + " (" +
                trimmed(PQerrorMessage(conn_.get())) + ")");
  description_ = describe(conn_.get());
  PQsetNoticeProcessor(conn_.get(), ignore_notice, nullptr);
}

void PgDb::exec(std::string_view sql) {
  const std::string text(sql);
  std::unique_ptr<PGresult, decltype(&PQclear)> result(PQexec(conn_.get(), text.c_str()), &PQclear);
  const ExecStatusType status = result ? PQresultStatus(result.get()) : PGRES_FATAL_ERROR;
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK && status != PGRES_EMPTY_QUERY)
    throw_result(result.get(), conn_.get(), "executing SQL");
}

PgStatement PgDb::prepare(std::string_view sql) {
  int parameters = 0;
  std::string translated = sqlite_params_to_postgres(sql, &parameters);
  return PgStatement(conn_.get(), prepared_.get(), description_, std::move(translated), parameters);
}

std::unique_ptr<SqlStatement> PgDb::prepare_statement(std::string_view sql) {
  return std::make_unique<PgStatement>(prepare(sql));
}

void PgDb::begin_transaction(SqlTransactionMode mode) {
  exec(mode == SqlTransactionMode::kRead ? "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY" : "BEGIN");
}

}  // namespace orbatlas
