#pragma once
// Where an atlas lives: an SQLite file, given by its path, or a
// PostgreSQL database, given as a libpq URI (`postgresql://user@host:port/db`
// or `postgres://...`). Everything that opens an atlas by "path" (AtlasStore::open,
// AtlasCheckpointer, DatabaseLock, `--db` / `--atlas`) takes either.
#include <string>
#include <string_view>

namespace orbatlas {

// True for `postgresql://...` and `postgres://...` (libpq's URI prefixes).
bool is_postgres_location(std::string_view location);

// Parses a PostgreSQL URI as libpq would, before connecting: Error saying
// what is wrong with it (libpq's message), with the password hidden.
void check_postgres_uri(const std::string& uri);

// The location for messages and logs: an SQLite path as it is, a PostgreSQL
// URI with its password replaced by "***".
std::string location_for_messages(const std::string& location);

}  // namespace orbatlas
