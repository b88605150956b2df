// Compiled with -mavx2 -mfma (see CMakeLists.txt); reached only through
// BestFfvaKernels() after a run-time CPU check.
#include <immintrin.h>

#include <cmath>

#include "mvkp/index/internal/ffva_kernels.h"

namespace mvkp::internal {
namespace {

inline __m256i Table(const std::uint8_t* lut) {
  return _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(lut)));
}

// Sums of B consecutive blocks, tables loaded once per pair for all B.
// With kEarlyExit, gives up on the blocks once every lane's partial sum exceeds
// thr (sums only grow, so those lanes cannot pass): checked every 4 pairs.
// The check costs more than it saves below ~32 dimensions (measured on WH
// 20-D: 2.6 -> 2.8-3.4 us per query at 4k), so it is used from 16 pairs up.
// Returns false when it gave up (acc then holds partial sums, all > thr).
template <int B, bool kEarlyExit>
inline bool SumsUpTo(const std::uint8_t* codes, int npairs, const std::uint8_t* luts, __m256i t, __m256i* acc) {
  const __m256i low4 = _mm256_set1_epi8(0x0F);
  const __m256i zero = _mm256_setzero_si256();
  for (int i = 0; i < B; ++i) acc[i] = zero;
  const std::size_t stride = std::size_t(npairs) * kBlockLanes;
  for (int p = 0; p < npairs; ++p) {
    const __m256i tlo = Table(luts + (2 * p) * 16);
    const __m256i thi = Table(luts + (2 * p + 1) * 16);
    for (int i = 0; i < B; ++i) {
      const __m256i c =
          _mm256_loadu_si256(reinterpret_cast<const __m256i*>(codes + i * stride + std::size_t(p) * kBlockLanes));
      const __m256i lo = _mm256_and_si256(c, low4);
      const __m256i hi = _mm256_and_si256(_mm256_srli_epi16(c, 4), low4);
      acc[i] = _mm256_adds_epu8(acc[i], _mm256_shuffle_epi8(tlo, lo));
      acc[i] = _mm256_adds_epu8(acc[i], _mm256_shuffle_epi8(thi, hi));
    }
    if (kEarlyExit && (p & 3) == 3 && p + 1 < npairs) {
      __m256i pass = _mm256_cmpeq_epi8(_mm256_subs_epu8(acc[0], t), zero);
      for (int i = 1; i < B; ++i) pass = _mm256_or_si256(pass, _mm256_cmpeq_epi8(_mm256_subs_epu8(acc[i], t), zero));
      if (_mm256_testz_si256(pass, pass)) return false;
    }
  }
  return true;
}

}  // namespace

void FastScanSumsAvx2(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                      std::uint8_t* sums) {
  const std::size_t stride = std::size_t(npairs) * kBlockLanes;
  for (std::size_t b = 0; b < nblocks; ++b) {
    __m256i acc[1];
    SumsUpTo<1, false>(codes + b * stride, npairs, luts, _mm256_setzero_si256(), acc);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(sums + b * kBlockLanes), acc[0]);
  }
}

template <bool kEarlyExit>
static void MasksImpl(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                      std::uint8_t thr, std::uint8_t* sums, std::uint32_t* masks) {
  const std::size_t stride = std::size_t(npairs) * kBlockLanes;
  const __m256i t = _mm256_set1_epi8(char(thr));
  const __m256i zero = _mm256_setzero_si256();
  // sum <= thr  <=>  saturating (sum - thr) == 0
  auto mask = [&](__m256i s) {
    return std::uint32_t(_mm256_movemask_epi8(_mm256_cmpeq_epi8(_mm256_subs_epu8(s, t), zero)));
  };
  std::size_t b = 0;
  for (; b + 2 <= nblocks; b += 2) {
    __m256i acc[2];
    if (!SumsUpTo<2, kEarlyExit>(codes + b * stride, npairs, luts, t, acc)) {
      masks[b] = masks[b + 1] = 0;
      continue;
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(sums + b * kBlockLanes), acc[0]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(sums + (b + 1) * kBlockLanes), acc[1]);
    masks[b] = mask(acc[0]);
    masks[b + 1] = mask(acc[1]);
  }
  if (b < nblocks) {
    __m256i acc[1];
    if (!SumsUpTo<1, kEarlyExit>(codes + b * stride, npairs, luts, t, acc)) {
      masks[b] = 0;
      return;
    }
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(sums + b * kBlockLanes), acc[0]);
    masks[b] = mask(acc[0]);
  }
}

void FastScanMasksAvx2(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                      std::uint8_t thr, std::uint8_t* sums, std::uint32_t* masks) {
  if (npairs >= 16) {
    MasksImpl<true>(codes, nblocks, npairs, luts, thr, sums, masks);
  } else {
    MasksImpl<false>(codes, nblocks, npairs, luts, thr, sums, masks);
  }
}

float BoxDistanceAvx2(const float* lo, const float* hi, const float* q, int dim) {
  __m256 acc = _mm256_setzero_ps();
  const __m256 zero = _mm256_setzero_ps();
  int d = 0;
  for (; d + 8 <= dim; d += 8) {
    const __m256 x = _mm256_loadu_ps(q + d);
    const __m256 g = _mm256_max_ps(zero, _mm256_max_ps(_mm256_sub_ps(_mm256_loadu_ps(lo + d), x),
                                                       _mm256_sub_ps(x, _mm256_loadu_ps(hi + d))));
    acc = _mm256_fmadd_ps(g, g, acc);
  }
  if (d < dim) {
    alignas(32) static const int kTail[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
    const __m256i m = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kTail + 8 - (dim - d)));
    const __m256 x = _mm256_maskload_ps(q + d, m);
    const __m256 g = _mm256_max_ps(zero, _mm256_max_ps(_mm256_sub_ps(_mm256_maskload_ps(lo + d, m), x),
                                                       _mm256_sub_ps(x, _mm256_maskload_ps(hi + d, m))));
    acc = _mm256_fmadd_ps(g, g, acc);
  }
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps(acc, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_movehdup_ps(s));
  return _mm_cvtss_f32(s);
}

void GapTablesAvx2(const float* cells, const float* q, int dim, int rows, float shrink, float* bound) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 k = _mm256_set1_ps(shrink);
  for (int j = 0; j < dim; ++j) {
    const float* e = cells + std::size_t(j) * 17;
    const __m256 x = _mm256_set1_ps(q[j]);
    for (int h = 0; h < 16; h += 8) {
      const __m256 lo = _mm256_sub_ps(_mm256_loadu_ps(e + h), x);
      const __m256 hi = _mm256_sub_ps(x, _mm256_loadu_ps(e + h + 1));
      const __m256 g = _mm256_max_ps(zero, _mm256_max_ps(lo, hi));
      // Same operation order as the scalar reference: (g * g) * shrink.
      _mm256_storeu_ps(bound + j * 16 + h, _mm256_mul_ps(_mm256_mul_ps(g, g), k));
    }
  }
  for (int j = dim; j < rows; ++j) {
    _mm256_storeu_ps(bound + j * 16, zero);
    _mm256_storeu_ps(bound + j * 16 + 8, zero);
  }
}

void QuantiseAvx2(const float* bound, std::size_t count, float inv_scale, std::uint8_t* lut) {
  const __m256 s = _mm256_set1_ps(inv_scale);
  const __m256 top = _mm256_set1_ps(255.f);
  for (std::size_t i = 0; i < count; i += 16) {
    const __m256i a = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_mul_ps(_mm256_loadu_ps(bound + i), s), top));
    const __m256i b = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_mul_ps(_mm256_loadu_ps(bound + i + 8), s), top));
    // 16 int32 in [0, 255] -> 16 bytes (packs work per 128-bit lane: fix the order).
    const __m256i w = _mm256_permute4x64_epi64(_mm256_packus_epi32(a, b), 0xD8);
    const __m128i bytes = _mm_packus_epi16(_mm256_castsi256_si128(w), _mm256_extracti128_si256(w, 1));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(lut + i), bytes);
  }
}

float L2SequentialFma(const float* x, const float* q, int dim) {
  float acc = 0.f;
  for (int d = 0; d < dim; ++d) {
    const float diff = x[d] - q[d];
    acc = std::fma(diff, diff, acc);  // one vfmadd per dimension under -mfma
  }
  return acc;
}

}  // namespace mvkp::internal
