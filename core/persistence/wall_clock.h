#pragma once
// Wall-clock time for the database's created_ns / saved_ns / applied_ns columns.
#include <chrono>

#include "core/common/timestamp.h"

namespace orbatlas {

inline TimestampNs unix_time_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace orbatlas
