#pragma once
// Elapsed wall time for the timing figures (stats JSON, benchmarks).
#include <chrono>

namespace orbatlas {

inline double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace orbatlas
