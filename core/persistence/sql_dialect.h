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

// The queries are written with SQLite's parameter marks; PostgreSQL numbers
// them: `?NNN` and `?` -> `$NNN` outside quoted strings and identifiers (a bare
// `?` is one more than the largest number so far, as in SQLite).
// `parameter_count`, when given, receives the largest parameter number (0 for none).
std::string sqlite_params_to_postgres(std::string_view sql, int* parameter_count = nullptr);

}  // namespace orbatlas
