#include "core/common/log.h"

#include <cstdio>
#include <string>

namespace orbatlas {
namespace {
void write_line(std::string_view prefix, std::string_view message) {
  std::string line;
  line.reserve(prefix.size() + message.size() + 1);
  line.append(prefix).append(message).push_back('\n');
  std::fwrite(line.data(), 1, line.size(), stderr);  // one write per line
}
}  // namespace

void log_info(std::string_view message) { write_line("[orbatlas] ", message); }
void log_warn(std::string_view message) { write_line("[orbatlas] warning: ", message); }

}  // namespace orbatlas
