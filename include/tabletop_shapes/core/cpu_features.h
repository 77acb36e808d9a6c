// What the CPU running the process can do, asked once: which SIMD variant of a loop to take.
#pragma once

#include <cstdlib>

namespace tabletop_shapes {

// True where the CPU has AVX2 (functions built with target("avx2") may run); false elsewhere,
// where the compiler cannot ask (not GCC / Clang on x86-64), and when the environment sets
// TABLETOP_SHAPES_NO_AVX2 (to run the four-lane fallbacks, which older CPUs take, on this one:
// their answers must be the same bit for bit).
inline bool cpuHasAvx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has_avx2 = [] {
    if (std::getenv("TABLETOP_SHAPES_NO_AVX2")) return false;
    __builtin_cpu_init();  // also when called from a static initialiser, before main
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has_avx2;
#else
  return false;
#endif
}

}  // namespace tabletop_shapes
