// Compiled with -mavx2 -mfma (see CMakeLists.txt); reached only through
// BestL2Blocks8() after a run-time CPU check.
#include <immintrin.h>

#include <algorithm>
#include <limits>
#include <vector>

#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp::internal {

void L2Blocks8Avx2(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out) {
  // Four blocks at a time: four independent accumulator chains hide the FMA
  // latency (one chain per block left the kernel latency-bound). Each lane
  // still sums its dimensions in the same order, so the distances are
  // bit-identical to one block at a time and to the scalar reference.
  const std::size_t stride = std::size_t(dim) * kLanes;
  std::size_t b = 0;
  for (; b + 4 <= nblocks; b += 4) {
    const float* b0 = blocks + b * stride;
    __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
    for (int d = 0; d < dim; ++d) {
      const __m256 qd = _mm256_set1_ps(q[d]);
      const float* x = b0 + d * kLanes;
      const __m256 x0 = _mm256_sub_ps(_mm256_loadu_ps(x), qd);
      const __m256 x1 = _mm256_sub_ps(_mm256_loadu_ps(x + stride), qd);
      const __m256 x2 = _mm256_sub_ps(_mm256_loadu_ps(x + 2 * stride), qd);
      const __m256 x3 = _mm256_sub_ps(_mm256_loadu_ps(x + 3 * stride), qd);
      a0 = _mm256_fmadd_ps(x0, x0, a0);
      a1 = _mm256_fmadd_ps(x1, x1, a1);
      a2 = _mm256_fmadd_ps(x2, x2, a2);
      a3 = _mm256_fmadd_ps(x3, x3, a3);
    }
    _mm256_storeu_ps(out + b * kLanes, a0);
    _mm256_storeu_ps(out + (b + 1) * kLanes, a1);
    _mm256_storeu_ps(out + (b + 2) * kLanes, a2);
    _mm256_storeu_ps(out + (b + 3) * kLanes, a3);
  }
  for (; b < nblocks; ++b) {
    const float* blk = blocks + b * stride;
    __m256 acc = _mm256_setzero_ps();
    for (int d = 0; d < dim; ++d) {
      const __m256 x = _mm256_sub_ps(_mm256_loadu_ps(blk + d * kLanes), _mm256_set1_ps(q[d]));
      acc = _mm256_fmadd_ps(x, x, acc);
    }
    _mm256_storeu_ps(out + b * kLanes, acc);
  }
}

namespace {

template <int Q>
void TwoDistinctNormQ(const float* blocks, const float* norms, const std::int32_t* labels, std::size_t nblocks,
                      const float* queries, const float* qnorms, int dim, TopTwo* t) {
  __m256 bound[Q], qn[Q];
  for (int k = 0; k < Q; ++k) {
    bound[k] = _mm256_set1_ps(t[k].Bound());
    qn[k] = _mm256_set1_ps(qnorms[k]);
  }
  // -2 q, once: the inner loop then broadcasts straight from memory.
  float qm2[Q * 128];
  const bool small = dim <= 128;
  if (small)
    for (int i = 0; i < Q * dim; ++i) qm2[i] = -2.f * queries[i];
  const __m256 zero = _mm256_setzero_ps();
  // Block b's distances in acc: offered to each query's top two in lane order.
  auto offer = [&](std::size_t b, const __m256* acc) {
    for (int k = 0; k < Q; ++k) {
      int mask = _mm256_movemask_ps(_mm256_cmp_ps(acc[k], bound[k], _CMP_LT_OQ));
      if (__builtin_expect(mask == 0, 1)) continue;
      alignas(32) float dist[kLanes];
      _mm256_store_ps(dist, _mm256_max_ps(acc[k], zero));
      const std::int32_t* lab = labels + b * kLanes;
      while (mask) {
        const int l = __builtin_ctz(unsigned(mask));
        mask &= mask - 1;
        TopTwoOffer(t[k], dist[l], std::int32_t(b * kLanes + l), lab[l]);
      }
      bound[k] = _mm256_set1_ps(t[k].Bound());
    }
  };
  std::size_t b = 0;
  if (small) {
    // Two blocks at a time: twice the independent FMA chains, and each
    // broadcast query value serves both. Offered in block order, so the
    // result is the one-block loop's.
    for (; b + 2 <= nblocks; b += 2) {
      const float* blk0 = blocks + b * std::size_t(dim) * kLanes;
      const float* blk1 = blk0 + std::size_t(dim) * kLanes;
      const __m256 xn0 = _mm256_loadu_ps(norms + b * kLanes), xn1 = _mm256_loadu_ps(norms + (b + 1) * kLanes);
      __m256 acc0[Q], acc1[Q];
      for (int k = 0; k < Q; ++k) {
        acc0[k] = _mm256_add_ps(xn0, qn[k]);
        acc1[k] = _mm256_add_ps(xn1, qn[k]);
      }
      for (int d = 0; d < dim; ++d) {
        const __m256 row0 = _mm256_loadu_ps(blk0 + d * kLanes), row1 = _mm256_loadu_ps(blk1 + d * kLanes);
        for (int k = 0; k < Q; ++k) {
          const __m256 qv = _mm256_broadcast_ss(qm2 + k * dim + d);
          acc0[k] = _mm256_fmadd_ps(qv, row0, acc0[k]);
          acc1[k] = _mm256_fmadd_ps(qv, row1, acc1[k]);
        }
      }
      // Copies: the accumulators themselves must not escape to memory, or
      // they are kept there through the loop above.
      __m256 out0[Q], out1[Q];
      for (int k = 0; k < Q; ++k) {
        out0[k] = acc0[k];
        out1[k] = acc1[k];
      }
      offer(b, out0);
      offer(b + 1, out1);
    }
  }
  for (; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    const __m256 xn = _mm256_loadu_ps(norms + b * kLanes);
    __m256 acc[Q];
    for (int k = 0; k < Q; ++k) acc[k] = _mm256_add_ps(xn, qn[k]);
    if (small) {
      for (int d = 0; d < dim; ++d) {
        const __m256 row = _mm256_loadu_ps(blk + d * kLanes);
        for (int k = 0; k < Q; ++k) acc[k] = _mm256_fmadd_ps(_mm256_broadcast_ss(qm2 + k * dim + d), row, acc[k]);
      }
    } else {
      for (int d = 0; d < dim; ++d) {
        const __m256 row = _mm256_loadu_ps(blk + d * kLanes);
        for (int k = 0; k < Q; ++k)
          acc[k] = _mm256_fmadd_ps(_mm256_set1_ps(-2.f * queries[k * dim + d]), row, acc[k]);
      }
    }
    __m256 out[Q];
    for (int k = 0; k < Q; ++k) out[k] = acc[k];
    offer(b, out);
  }
}

}  // namespace

void NearestRowsAvx2(const float* rows, std::size_t n, int dim, const float* queries, std::size_t nq, int k,
                     std::int32_t* out) {
  constexpr int K = kMaxNearest;
  std::vector<float> qt(std::size_t(dim) * kLanes);  // [d][lane]: eight queries, transposed
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  for (std::size_t first = 0; first < nq; first += kLanes) {
    const std::size_t m = std::min<std::size_t>(kLanes, nq - first);
    for (int d = 0; d < dim; ++d)
      for (int l = 0; l < kLanes; ++l)  // spare lanes repeat the group's first query
        qt[std::size_t(d) * kLanes + std::size_t(l)] = queries[(first + (std::size_t(l) < m ? l : 0)) * std::size_t(dim) + d];
    __m256 bd[K];
    __m256i bi[K];
    for (int j = 0; j < K; ++j) {
      bd[j] = inf;
      bi[j] = _mm256_set1_epi32(-1);
    }
    // Sorted insertion of one row's distances into every lane's slots: the
    // row goes before the first slot it is strictly below (ties stay after
    // the earlier row), and every later slot shifts down by one.
    auto insert = [&](__m256 x, std::int32_t row) {
      __m256i xi = _mm256_set1_epi32(row);
      __m256 moving = _mm256_setzero_ps();
      for (int j = 0; j < K; ++j) {
        const __m256 m = _mm256_or_ps(moving, _mm256_cmp_ps(x, bd[j], _CMP_LT_OQ));
        const __m256 t = bd[j];
        const __m256i ti = bi[j];
        bd[j] = _mm256_blendv_ps(t, x, m);
        bi[j] = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(ti), _mm256_castsi256_ps(xi), m));
        x = _mm256_blendv_ps(x, t, m);
        xi = _mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(xi), _mm256_castsi256_ps(ti), m));
        moving = m;
      }
    };
    std::size_t r = 0;
    // Four rows at a time: four independent accumulator chains.
    for (; r + 4 <= n; r += 4) {
      const float* x0 = rows + r * std::size_t(dim);
      __m256 a0 = _mm256_setzero_ps(), a1 = a0, a2 = a0, a3 = a0;
      for (int d = 0; d < dim; ++d) {
        const __m256 q = _mm256_loadu_ps(&qt[std::size_t(d) * kLanes]);
        const __m256 e0 = _mm256_sub_ps(_mm256_set1_ps(x0[d]), q);
        const __m256 e1 = _mm256_sub_ps(_mm256_set1_ps(x0[dim + d]), q);
        const __m256 e2 = _mm256_sub_ps(_mm256_set1_ps(x0[2 * dim + d]), q);
        const __m256 e3 = _mm256_sub_ps(_mm256_set1_ps(x0[3 * dim + d]), q);
        a0 = _mm256_fmadd_ps(e0, e0, a0);
        a1 = _mm256_fmadd_ps(e1, e1, a1);
        a2 = _mm256_fmadd_ps(e2, e2, a2);
        a3 = _mm256_fmadd_ps(e3, e3, a3);
      }
      insert(a0, std::int32_t(r));
      insert(a1, std::int32_t(r + 1));
      insert(a2, std::int32_t(r + 2));
      insert(a3, std::int32_t(r + 3));
    }
    for (; r < n; ++r) {
      const float* x = rows + r * std::size_t(dim);
      __m256 a = _mm256_setzero_ps();
      for (int d = 0; d < dim; ++d) {
        const __m256 e = _mm256_sub_ps(_mm256_set1_ps(x[d]), _mm256_loadu_ps(&qt[std::size_t(d) * kLanes]));
        a = _mm256_fmadd_ps(e, e, a);
      }
      insert(a, std::int32_t(r));
    }
    alignas(32) std::int32_t ids[K][kLanes];
    for (int j = 0; j < K; ++j) _mm256_store_si256(reinterpret_cast<__m256i*>(ids[j]), bi[j]);
    for (std::size_t l = 0; l < m; ++l)
      for (int j = 0; j < k; ++j) out[(first + l) * std::size_t(k) + std::size_t(j)] = ids[j][l];
  }
}

void TwoDistinctNormAvx2(const float* blocks, const float* norms, const std::int32_t* labels, std::size_t nblocks,
                         const float* queries, const float* qnorms, int nq, int dim, TopTwo* t) {
  switch (nq) {
    case 1: return TwoDistinctNormQ<1>(blocks, norms, labels, nblocks, queries, qnorms, dim, t);
    case 2: return TwoDistinctNormQ<2>(blocks, norms, labels, nblocks, queries, qnorms, dim, t);
    case 3: return TwoDistinctNormQ<3>(blocks, norms, labels, nblocks, queries, qnorms, dim, t);
    default: return TwoDistinctNormQ<4>(blocks, norms, labels, nblocks, queries, qnorms, dim, t);
  }
}

}  // namespace mvkp::internal
