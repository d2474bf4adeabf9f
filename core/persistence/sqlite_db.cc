#include "core/persistence/sqlite_db.h"

#include <sqlite3.h>

#include "core/common/error.h"

namespace orbatlas {
namespace {

// Failures that mean "this file is not (or no longer) a sound database": bad
// input data, as opposed to a misuse or an environment problem.
bool is_data_error(int rc) {
  const int primary = rc & 0xff;
  return primary == SQLITE_NOTADB || primary == SQLITE_CORRUPT || primary == SQLITE_FORMAT;
}

[[noreturn]] void throw_sqlite(int rc, const std::string& file, std::string_view context, const char* sqlite_message) {
  const std::string detail = std::string(context) + ": " + (sqlite_message ? sqlite_message : sqlite3_errstr(rc));
  const std::string message =
      (rc & 0xff) == SQLITE_NOTADB ? file + ": not an SQLite database (" + detail + ")" : file + ": " + detail;
  if (is_data_error(rc)) throw DataError(message);
  throw Error(message);
}

std::string statement_file(sqlite3_stmt* stmt) {
  const char* name = sqlite3_db_filename(sqlite3_db_handle(stmt), "main");
  return name ? name : "(sqlite)";
}

}  // namespace

// --- SqliteStatement ---

void SqliteStatement::Finalizer::operator()(sqlite3_stmt* stmt) const { sqlite3_finalize(stmt); }

void SqliteStatement::fail(int rc, std::string_view context) const {
  throw_sqlite(rc, statement_file(stmt_.get()), std::string(context) + " in \"" + sqlite3_sql(stmt_.get()) + "\"",
               sqlite3_errmsg(sqlite3_db_handle(stmt_.get())));
}

void SqliteStatement::check_bind(int rc, int index) const {
  if (rc != SQLITE_OK) fail(rc, "binding parameter " + std::to_string(index));
}

SqliteStatement& SqliteStatement::bind_int64(int index, std::int64_t value) {
  check_bind(sqlite3_bind_int64(stmt_.get(), index, value), index);
  return *this;
}

SqliteStatement& SqliteStatement::bind_real(int index, double value) {
  check_bind(sqlite3_bind_double(stmt_.get(), index, value), index);
  return *this;
}

SqliteStatement& SqliteStatement::bind_text(int index, std::string_view text) {
  check_bind(sqlite3_bind_text64(stmt_.get(), index, text.data(), text.size(), SQLITE_TRANSIENT, SQLITE_UTF8), index);
  return *this;
}

SqliteStatement& SqliteStatement::bind_blob(int index, std::string_view bytes) {
  // sqlite3_bind_blob with a null pointer binds NULL; an empty blob must stay a blob.
  const int rc = bytes.empty() ? sqlite3_bind_zeroblob(stmt_.get(), index, 0)
                               : sqlite3_bind_blob64(stmt_.get(), index, bytes.data(), bytes.size(), SQLITE_TRANSIENT);
  check_bind(rc, index);
  return *this;
}

SqliteStatement& SqliteStatement::bind_null(int index) {
  check_bind(sqlite3_bind_null(stmt_.get(), index), index);
  return *this;
}

bool SqliteStatement::step() {
  const int rc = sqlite3_step(stmt_.get());
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  fail(rc, "executing");
}

void SqliteStatement::run() {
  while (step()) {
  }
}

void SqliteStatement::reset() {
  // sqlite3_reset repeats the last step's error, which step() has already thrown.
  sqlite3_reset(stmt_.get());
  sqlite3_clear_bindings(stmt_.get());
}

bool SqliteStatement::is_null(int column) const { return sqlite3_column_type(stmt_.get(), column) == SQLITE_NULL; }

void SqliteStatement::check_type(int column, int expected, const char* expected_name) const {
  const int type = sqlite3_column_type(stmt_.get(), column);
  if (type == expected || (expected == SQLITE_FLOAT && type == SQLITE_INTEGER)) return;
  const char* name = sqlite3_column_name(stmt_.get(), column);
  throw DataError(statement_file(stmt_.get()) + ": column " + (name ? name : "?") + " holds " +
                  (type == SQLITE_NULL ? "NULL" : "a value of another type") + ", expected " + expected_name +
                  " (in \"" + sqlite3_sql(stmt_.get()) + "\")");
}

std::int64_t SqliteStatement::int64(int column) const {
  check_type(column, SQLITE_INTEGER, "an integer");
  return sqlite3_column_int64(stmt_.get(), column);
}

double SqliteStatement::real(int column) const {
  check_type(column, SQLITE_FLOAT, "a real");
  return sqlite3_column_double(stmt_.get(), column);
}

std::string SqliteStatement::text(int column) const {
  check_type(column, SQLITE_TEXT, "text");
  const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_.get(), column));
  return std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(stmt_.get(), column)));
}

std::string SqliteStatement::blob(int column) const {
  check_type(column, SQLITE_BLOB, "a blob");
  const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_.get(), column));
  const auto n = static_cast<std::size_t>(sqlite3_column_bytes(stmt_.get(), column));
  return n == 0 ? std::string() : std::string(p, n);
}

// --- SqliteDb ---

void SqliteDb::Closer::operator()(sqlite3* db) const { sqlite3_close_v2(db); }

SqliteDb::SqliteDb(const std::filesystem::path& path) : path_(path), description_(path.string()) {
  sqlite3* handle = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &handle, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
  db_.reset(handle);  // owned at once: even a failed open returns a handle to close
  if (rc != SQLITE_OK) {
    if (!db_) throw Error(path.string() + ": cannot open database: out of memory");
    fail(rc, "cannot open database");
  }
  sqlite3_extended_result_codes(db_.get(), 1);
  // Another process (or connection) writing: wait for it rather than fail at once.
  sqlite3_busy_timeout(db_.get(), 5000);
}

void SqliteDb::fail(int rc, std::string_view context) const {
  throw_sqlite(rc, path_.string(), context, db_ ? sqlite3_errmsg(db_.get()) : nullptr);
}

void SqliteDb::exec(std::string_view sql) {
  const std::string text(sql);  // sqlite3_exec needs a terminated string
  char* message = nullptr;
  const int rc = sqlite3_exec(db_.get(), text.c_str(), nullptr, nullptr, &message);
  if (rc == SQLITE_OK) return;
  const std::string detail = message ? message : sqlite3_errstr(rc);
  sqlite3_free(message);
  throw_sqlite(rc, path_.string(), "executing SQL", detail.c_str());
}

SqliteStatement SqliteDb::prepare(std::string_view sql) {
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v2(db_.get(), sql.data(), static_cast<int>(sql.size()), &stmt, nullptr);
  SqliteStatement statement(stmt);  // owned at once
  if (rc != SQLITE_OK) fail(rc, "preparing \"" + std::string(sql) + "\"");
  ORBATLAS_CHECK(stmt != nullptr, path_.string() << ": empty SQL statement");
  return statement;
}

std::unique_ptr<SqlStatement> SqliteDb::prepare_statement(std::string_view sql) {
  return std::make_unique<SqliteStatement>(prepare(sql));
}

void SqliteDb::begin_transaction(SqlTransactionMode mode) {
  exec(mode == SqlTransactionMode::kWrite ? "BEGIN IMMEDIATE" : "BEGIN DEFERRED");
}

}  // namespace orbatlas
