#include "core/persistence/sql_dialect.h"

namespace orbatlas {

std::string_view sql_dialect_name(SqlDialect dialect) {
  return dialect == SqlDialect::kSqlite ? "sqlite" : "postgresql";
}

std::string sql_greatest(SqlDialect dialect, std::string_view a, std::string_view b) {
  const std::string args = std::string(a) + ", " + std::string(b) + ")";
  return (dialect == SqlDialect::kSqlite ? "max(" : "GREATEST(") + args;
}

}  // namespace orbatlas
