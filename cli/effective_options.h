#pragma once
// What the two programs' command lines share (header only; the including target
// links CLI11): the options a command runs with, for the log line at start.
#include <CLI/CLI.hpp>
#include <sstream>
#include <string>

namespace orbatlas {

// Every option of `command` in effect (given on the command line, read from a
// --config file, or its default), one `name=value` per line in the config
// file's format, each line starting with `indent`; section headers are left
// out and the value of an option named `secret` is shown as "<set>" or "".
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
    out += indent + line + "\n";
  }
  return out;
}

}  // namespace orbatlas
