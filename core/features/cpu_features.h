#pragma once
// What the CPU running us can do, for code with a SIMD path chosen at run time
// (the binaries are built for baseline x86-64).

namespace orbatlas {

inline bool cpu_has_avx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool avx2 = __builtin_cpu_supports("avx2");  // set once, never changed
  return avx2;
#else
  return false;
#endif
}

}  // namespace orbatlas
