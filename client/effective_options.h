#pragma once
// What the two programs' command lines share (header only; the including target
// links CLI11): the options a command runs with, for the log line at start.
#include <CLI/CLI.hpp>
#include <sstream>
#include <string>

namespace orbatlas {

// `line` with the password of any URI in it (scheme://user:password@host, e.g.
// a PostgreSQL --db) shown as "***".
inline std::string without_uri_passwords(std::string line) {
  for (std::size_t from = 0; (from = line.find("://", from)) != std::string::npos; from += 3) {
    const std::size_t start = from + 3;
    const std::size_t end = line.find_first_of("/?\" \t", start);
    const std::size_t at = line.rfind('@', end == std::string::npos ? line.size() : end);
    if (at == std::string::npos || at < start) continue;
    const std::size_t colon = line.find(':', start);
    if (colon == std::string::npos || colon > at) continue;
    line.replace(colon + 1, at - colon - 1, "***");
  }
  return line;
}

// Every option of `command` in effect (given on the command line, read from a
// --config file, or its default), one `name=value` per line in the config
// file's format, each line starting with `indent`; section headers are left
// out, the value of an option named `secret` is shown as "<set>" or "", and a
// URI's password as "***".
inline std::string effective_options_text(const CLI::App& command, const std::string& indent = "  ",
                                          const std::string& secret = "token") {
  std::istringstream all(command.config_to_str(true, false));
  std::string out;
  for (std::string line; std::getline(all, line);) {
    if (line.empty() || line.front() == '[') continue;
    if (!secret.empty() && (line.rfind(secret + "=", 0) == 0 || line.rfind(secret + " =", 0) == 0)) {
      const bool empty = line.find('"') == std::string::npos || line.find("\"\"") != std::string::npos;
      line = secret + (empty ? "=\"\"" : "=\"<set>\"");
    }
    out += indent + without_uri_passwords(line) + "\n";
  }
  return out;
}

}  // namespace orbatlas
