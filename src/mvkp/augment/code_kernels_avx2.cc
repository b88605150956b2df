// Compiled with -mavx2 -mpopcnt (see CMakeLists.txt); reached only through
// BestSumSqDiffRows() after a run-time CPU check.
#include <immintrin.h>

#include <bit>

#include "mvkp/augment/internal/code_kernels.h"
#include "mvkp/augment/internal/code_loops.h"

namespace mvkp::augment_internal {

namespace {

inline std::int32_t HorizontalSum(__m256i v) {
  __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(1, 0, 3, 2)));
  s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(s);
}

// 16 bytes of q against 16 bytes of x: pairs of squared differences in int32.
inline __m256i SqDiff16(__m256i q16, const std::uint8_t* x) {
  const __m256i x16 = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(x)));
  const __m256i d = _mm256_sub_epi16(q16, x16);
  return _mm256_madd_epi16(d, d);
}

}  // namespace

void SumSqDiffRowsAvx2(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                       std::int32_t* out) {
  const int vec = dim / 16 * 16;
  // Widened query, loaded once (dim <= 255: at most 16 registers' worth).
  __m256i qw[16];
  for (int j = 0; j < vec; j += 16)
    qw[j / 16] = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(q + j)));
  std::size_t r = 0;
  // Two rows at a time for more independent work per query load.
  for (; r + 2 <= n; r += 2) {
    const std::uint8_t* x0 = rows + r * std::size_t(dim);
    const std::uint8_t* x1 = x0 + dim;
    __m256i a0 = _mm256_setzero_si256(), a1 = _mm256_setzero_si256();
    for (int j = 0; j < vec; j += 16) {
      a0 = _mm256_add_epi32(a0, SqDiff16(qw[j / 16], x0 + j));
      a1 = _mm256_add_epi32(a1, SqDiff16(qw[j / 16], x1 + j));
    }
    std::int32_t s0 = HorizontalSum(a0), s1 = HorizontalSum(a1);
    for (int j = vec; j < dim; ++j) {
      const std::int32_t d0 = std::int32_t(q[j]) - std::int32_t(x0[j]);
      const std::int32_t d1 = std::int32_t(q[j]) - std::int32_t(x1[j]);
      s0 += d0 * d0;
      s1 += d1 * d1;
    }
    out[r] = s0;
    out[r + 1] = s1;
  }
  if (r < n) SumSqDiffRowsScalar(q, rows + r * std::size_t(dim), n - r, dim, out + r);
}

// The scalar reference's loop, auto-vectorised with AVX2.
void CountDiffRowsAvx2(const std::uint8_t* q, const std::uint8_t* rows, std::size_t n, int dim,
                       std::int32_t* out) {
  CountDiffRowsLoop(q, rows, n, dim, out);
}

// The scalar reference's loop, here compiled to hardware popcnt.
void XorPopcountRowsAvx2(const std::uint64_t* q, const std::uint64_t* rows, std::size_t n, int words,
                         std::int32_t* out) {
  XorPopcountRowsLoop(q, rows, n, words, out);
}

}  // namespace mvkp::augment_internal
