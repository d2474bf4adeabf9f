#include "core/persistence/sql_connection.h"

#include "core/common/error.h"

namespace orbatlas {

std::int64_t SqlConnection::query_int64(std::string_view sql) {
  const std::unique_ptr<SqlStatement> statement = prepare_statement(sql);
  ORBATLAS_CHECK(statement->step(), description() << ": \"" << sql << "\" returned no row");
  return statement->int64(0);
}

SqlTransaction::SqlTransaction(SqlConnection& db, Mode mode) : db_(db) { db_.begin_transaction(mode); }

SqlTransaction::~SqlTransaction() {
  if (!open_) return;
  try {
    db_.exec("ROLLBACK");
  } catch (const Error&) {
    // SQLite may already have rolled back (e.g. after SQLITE_FULL), a PostgreSQL
    // connection may be gone (the server rolls back what it never saw committed).
  }
}

void SqlTransaction::commit() {
  ORBATLAS_CHECK(open_, db_.description() << ": transaction committed twice");
  db_.exec("COMMIT");
  open_ = false;
}

}  // namespace orbatlas
