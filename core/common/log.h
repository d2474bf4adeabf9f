#pragma once
// Minimal logging to stderr. Each call writes one whole line, so lines from
// different threads do not interleave.
#include <string_view>

namespace orbatlas {

void log_info(std::string_view message);
void log_warn(std::string_view message);

}  // namespace orbatlas
