// What the CPU can run, asked once: the SIMD kernels (`*_avx2.cc`) are
// chosen at run time, the build has no -march=native.
#pragma once

namespace mvkp::internal {

// AVX2 (the kernels built with -mavx2 and no FMA).
inline bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}

}  // namespace mvkp::internal
