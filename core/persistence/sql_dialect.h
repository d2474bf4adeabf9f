#pragma once
// The few places where the atlas's SQL differs between SQLite and PostgreSQL.
// Everything else is written once in what both accept (e.g. INSERT ... ON
// CONFLICT ... DO NOTHING / DO UPDATE, coalesce, JOIN ... ORDER BY).
#include <string>
#include <string_view>

namespace orbatlas {

enum class SqlDialect { kSqlite, kPostgres };

// "sqlite" / "postgresql", for messages and test names.
std::string_view sql_dialect_name(SqlDialect dialect);

// The larger of two values: SQLite's scalar max(a, b), PostgreSQL's GREATEST(a, b).
std::string sql_greatest(SqlDialect dialect, std::string_view a, std::string_view b);

}  // namespace orbatlas
