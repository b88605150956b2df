// Distance kernels over vectors stored in blocks of 8, transposed:
// block[d * 8 + lane] is dimension d of vector lane. Internal to mvkp_index.
#pragma once

#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <limits>

namespace mvkp::internal {

constexpr int kLanes = 8;

// out[lane] = sum_d (block[d*8+lane] - q[d])^2 for `nblocks` consecutive blocks
// (out holds nblocks*8 floats). Scalar reference.
void L2Blocks8Scalar(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out);
// The same with AVX2+FMA; call only when CpuHasAvx2().
void L2Blocks8Avx2(const float* blocks, std::size_t nblocks, const float* q, int dim, float* out);

// Running state of a "nearest, and nearest with another label" search.
struct TopTwo {
  float d1, d2;            // squared distances
  std::int32_t id1, id2;   // -1 when unset
  std::int32_t lab1, lab2;
  // Squared ratio r^2 of a ratio test d1 < r * d2, or 0. With r > 0 the scan
  // may skip vectors at distance >= d1 / r^2: the nearest neighbour and the
  // outcome of the test stay exact, but d2 may be reported larger than the
  // true second distance when the test passes.
  float ratio2;
  float Bound() const { return ratio2 > 0 ? std::min(d2, d1 / ratio2) : d2; }
};
TopTwo EmptyTopTwo(float ratio = 0.f);

// Candidate update shared by both kernels.
inline void TopTwoOffer(TopTwo& t, float d, std::int32_t id, std::int32_t lab) {
  if (d >= t.Bound() || lab < 0) return;
  if (d < t.d1) {
    if (lab != t.lab1) {
      t.d2 = t.d1;
      t.id2 = t.id1;
      t.lab2 = t.lab1;
    }
    t.d1 = d;
    t.id1 = id;
    t.lab1 = lab;
  } else if (lab != t.lab1) {
    t.d2 = d;
    t.id2 = id;
    t.lab2 = lab;
  }
}

// Batched form through the expansion |x - q|^2 = |x|^2 + |q|^2 - 2 x.q:
// `norms` holds |x|^2 per lane (padding lanes: +inf), `queries` holds nq
// queries of `dim` floats (nq in 1..4) with their squared norms in `qnorms`,
// and t[0..nq) is updated for each. Each stored row is loaded once for all
// nq queries. Both versions accumulate in the same order with fused
// multiply-adds and clamp at 0, so they agree bit for bit.
void TwoDistinctNormScalar(const float* blocks, const float* norms, const std::int32_t* labels, std::size_t nblocks,
                           const float* queries, const float* qnorms, int nq, int dim, TopTwo* t);
void TwoDistinctNormAvx2(const float* blocks, const float* norms, const std::int32_t* labels, std::size_t nblocks,
                         const float* queries, const float* qnorms, int nq, int dim, TopTwo* t);
using TwoDistinctNormFn = void (*)(const float*, const float*, const std::int32_t*, std::size_t, const float*,
                                   const float*, int, int, TopTwo*);
TwoDistinctNormFn BestTwoDistinctNorm();

// The k nearest (k in 1..kMaxNearest) of n row-major vectors (n x dim) to
// each of nq queries: out[i * k + j] is the row of query i's j-th nearest,
// nearest first, ties by row (the first stored wins), -1 past n. Distances
// are L2Blocks8's (fused multiply-adds of (x - q)^2 in dimension order), so
// the rows are those of a scan with L2Blocks8 and a stable insertion. The
// AVX2 version puts eight queries in the lanes and inserts each row into
// eight sorted slots per lane without a branch; the IVF's coarse probe
// (87 lists, 8 probed) spent most of its time in the insertion's branches.
constexpr int kMaxNearest = 8;
void NearestRowsScalar(const float* rows, std::size_t n, int dim, const float* queries, std::size_t nq, int k,
                       std::int32_t* out);
void NearestRowsAvx2(const float* rows, std::size_t n, int dim, const float* queries, std::size_t nq, int k,
                     std::int32_t* out);
using NearestRowsFn = void (*)(const float*, std::size_t, int, const float*, std::size_t, int, std::int32_t*);
NearestRowsFn BestNearestRows();

// |x|^2 accumulated with fused multiply-adds in dimension order.
float SquaredNorm(const float* x, int dim);

bool CpuHasAvx2();

// Throws Error(kInvalidArgument) "<what> has a NaN or infinite value (vector i)"
// when any of the n vectors of `dim` floats is not finite.
void RequireFinite(const float* data, std::size_t n, int dim, const char* what);

using L2Blocks8Fn = void (*)(const float*, std::size_t, const float*, int, float*);
// The fastest kernel this CPU runs, chosen once.
L2Blocks8Fn BestL2Blocks8();

}  // namespace mvkp::internal
