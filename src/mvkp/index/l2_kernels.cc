#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp::internal {

void L2Blocks8Scalar(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    float acc[kLanes] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int d = 0; d < dim; ++d) {
      const float qd = q[d];
      for (int l = 0; l < kLanes; ++l) {
        const float diff = blk[d * kLanes + l] - qd;
        acc[l] += diff * diff;
      }
    }
    for (int l = 0; l < kLanes; ++l) out[b * kLanes + l] = acc[l];
  }
}

bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }();
  return has;
}

L2Blocks8Fn BestL2Blocks8() {
  static const L2Blocks8Fn fn = CpuHasAvx2() ? &L2Blocks8Avx2 : &L2Blocks8Scalar;
  return fn;
}

}  // namespace mvkp::internal
