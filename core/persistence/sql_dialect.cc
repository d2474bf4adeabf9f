#include "core/persistence/sql_dialect.h"

#include <algorithm>
#include <cctype>
#include <string>

namespace orbatlas {

std::string_view sql_dialect_name(SqlDialect dialect) {
  return dialect == SqlDialect::kSqlite ? "sqlite" : "postgresql";
}

std::string sql_greatest(SqlDialect dialect, std::string_view a, std::string_view b) {
  const std::string args = std::string(a) + ", " + std::string(b) + ")";
  return (dialect == SqlDialect::kSqlite ? "max(" : "GREATEST(") + args;
}

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

}  // namespace orbatlas
