#include "core/persistence/atlas_location.h"

#include <libpq-fe.h>

#include <memory>

#include "core/common/error.h"

namespace orbatlas {

bool is_postgres_location(std::string_view location) {
  return location.starts_with("postgresql://") || location.starts_with("postgres://");
}

std::string location_for_messages(const std::string& location) {
  if (!is_postgres_location(location)) return location;
  // postgresql://user:password@host/...: the password sits between the first
  // ':' after the scheme and the '@' that ends the user part.
  const std::size_t start = location.find("://") + 3;
  const std::size_t at = location.find('@', start);
  const std::size_t slash = location.find('/', start);
  if (at == std::string::npos || (slash != std::string::npos && slash < at)) return location;
  const std::size_t colon = location.find(':', start);
  if (colon == std::string::npos || colon > at) return location;
  return location.substr(0, colon + 1) + "***" + location.substr(at);
}

void check_postgres_uri(const std::string& uri) {
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(uri.c_str(), &error);
  const std::unique_ptr<char, decltype(&PQfreemem)> message(error, &PQfreemem);
  if (options) {
    PQconninfoFree(options);
    return;
  }
  std::string detail = error ? error : "out of memory";
  while (!detail.empty() && (detail.back() == '\n' || detail.back() == ' ')) detail.pop_back();
  // libpq quotes the URI in some messages: never its password.
  const std::string shown = location_for_messages(uri);
  for (std::size_t at; (at = detail.find(uri)) != std::string::npos;) detail.replace(at, uri.size(), shown);
  throw Error("bad PostgreSQL URI " + location_for_messages(uri) + ": " + detail +
              " (expected postgresql://[user[:password]@][host][:port][/dbname][?param=value&...])");
}

}  // namespace orbatlas
