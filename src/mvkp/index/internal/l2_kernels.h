// Distance kernels over vectors stored in blocks of 8, transposed:
// block[d * 8 + lane] is dimension d of vector lane. Internal to mvkp_index.
#pragma once

#include <cstddef>

namespace mvkp::internal {

constexpr int kLanes = 8;

// out[lane] = sum_d (block[d*8+lane] - q[d])^2 for `nblocks` consecutive blocks
// (out holds nblocks*8 floats). Scalar reference.
void L2Blocks8Scalar(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out);
// The same with AVX2+FMA; call only when CpuHasAvx2().
void L2Blocks8Avx2(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out);

bool CpuHasAvx2();

using L2Blocks8Fn = void (*)(const float*, std::size_t, const float*, int, float*);
// The fastest kernel this CPU runs, chosen once.
L2Blocks8Fn BestL2Blocks8();

}  // namespace mvkp::internal
