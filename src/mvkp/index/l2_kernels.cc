#include "mvkp/index/internal/l2_kernels.h"

#include <cmath>
#include <cstring>
#include <string>

#include "mvkp/core/error.h"

namespace mvkp::internal {

void L2Blocks8Scalar(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    float acc[kLanes] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (int d = 0; d < dim; ++d) {
      const float qd = q[d];
      for (int l = 0; l < kLanes; ++l) {
        const float diff = blk[d * kLanes + l] - qd;
        acc[l] = std::fma(diff, diff, acc[l]);  // as the SIMD kernels do: bit-identical
      }
    }
    for (int l = 0; l < kLanes; ++l) out[b * kLanes + l] = acc[l];
  }
}

void NearestRowsScalar(const float* rows, std::size_t n, int dim, const float* queries, std::size_t nq, int k,
                       std::int32_t* out) {
  for (std::size_t i = 0; i < nq; ++i) {
    const float* q = queries + i * std::size_t(dim);
    float best[kMaxNearest];
    std::int32_t* o = out + i * std::size_t(k);
    for (int j = 0; j < k; ++j) {
      best[j] = std::numeric_limits<float>::infinity();
      o[j] = -1;
    }
    for (std::size_t r = 0; r < n; ++r) {
      const float* x = rows + r * std::size_t(dim);
      float acc = 0.f;
      for (int d = 0; d < dim; ++d) {
        const float diff = x[d] - q[d];
        acc = std::fma(diff, diff, acc);
      }
      if (!(acc < best[k - 1])) continue;
      int p = k - 1;
      while (p > 0 && best[p - 1] > acc) {
        best[p] = best[p - 1];
        o[p] = o[p - 1];
        --p;
      }
      best[p] = acc;
      o[p] = std::int32_t(r);
    }
  }
}

NearestRowsFn BestNearestRows() {
  static const NearestRowsFn fn = CpuHasAvx2() ? &NearestRowsAvx2 : &NearestRowsScalar;
  return fn;
}

TopTwo EmptyTopTwo(float ratio) {
  const float inf = std::numeric_limits<float>::infinity();
  return {inf, inf, -1, -1, -1, -1, ratio * ratio};
}

float SquaredNorm(const float* x, int dim) {
  float s = 0.f;
  for (int d = 0; d < dim; ++d) s = std::fma(x[d], x[d], s);
  return s;
}

void TwoDistinctNormScalar(const float* blocks, const float* norms, const std::int32_t* labels, std::size_t nblocks,
                           const float* queries, const float* qnorms, int nq, int dim, TopTwo* t) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const float* blk = blocks + b * std::size_t(dim) * kLanes;
    for (int qi = 0; qi < nq; ++qi) {
      const float* q = queries + std::size_t(qi) * dim;
      for (int l = 0; l < kLanes; ++l) {
        float acc = norms[b * kLanes + l] + qnorms[qi];
        for (int d = 0; d < dim; ++d) acc = std::fma(-2.f * q[d], blk[d * kLanes + l], acc);
        acc = std::max(acc, 0.f);
        TopTwoOffer(t[qi], acc, std::int32_t(b * kLanes + l), labels[b * kLanes + l]);
      }
    }
  }
}

TwoDistinctNormFn BestTwoDistinctNorm() {
  static const TwoDistinctNormFn fn = CpuHasAvx2() ? &TwoDistinctNormAvx2 : &TwoDistinctNormScalar;
  return fn;
}

void RequireFinite(const float* data, std::size_t n, int dim, const char* what) {
  const std::size_t total = n * std::size_t(dim);
  // Branch-free pass first (exponent all ones <=> NaN or inf; integer ops
  // vectorise without reassociating floats), then locate the culprit.
  std::uint32_t bad = 0;
  for (std::size_t i = 0; i < total; ++i) {
    std::uint32_t bits;
    std::memcpy(&bits, data + i, 4);
    bad |= std::uint32_t((bits & 0x7F800000u) == 0x7F800000u);
  }
  if (!bad) return;
  for (std::size_t i = 0; i < total; ++i) {
    if (!std::isfinite(data[i])) {
      throw Error(ErrorCode::kInvalidArgument, std::string(what) + " has a NaN or infinite value (vector " +
                                                   std::to_string(i / std::size_t(dim)) + ", dimension " +
                                                   std::to_string(i % std::size_t(dim)) + ")");
    }
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
