// AVX2 disc moments (compiled with -mavx2): one 32-byte row segment per disc
// row, multiplied by the row's masked weights (u) and ones with maddubs, the
// 16-bit pair sums widened and accumulated in 32-bit lanes (|sums| < 2^20).
#include <immintrin.h>

#include "mvkp/describe/internal/orient_kernels.h"

namespace mvkp::internal {

namespace {
std::int64_t HorizontalSum(__m256i v) {
  const __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  const __m128i t = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4e));
  const __m128i u = _mm_add_epi32(t, _mm_shuffle_epi32(t, 0xb1));
  return _mm_cvtsi128_si32(u);
}
}  // namespace

void DiscMomentsAvx2(const std::uint8_t* centre, std::ptrdiff_t step, const DiscTable& t, std::int64_t& m10,
                     std::int64_t& m01) {
  if (t.r > kMaxSimdRadius || t.ones.empty()) {
    DiscMomentsScalar(centre, step, t, m10, m01);
    return;
  }
  const __m256i one16 = _mm256_set1_epi16(1);
  __m256i acc10 = _mm256_setzero_si256(), acc01 = _mm256_setzero_si256();
  for (int v = -t.r; v <= t.r; ++v) {
    const __m256i px = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(centre + v * step - 15));
    const std::size_t k = std::size_t(v + t.r) * 32;
    const __m256i w = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(&t.weights[k]));
    const __m256i o = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(&t.ones[k]));
    // Pairs of u * I (|.| <= 255 * 29) and of I (<= 510): no 16-bit saturation.
    acc10 = _mm256_add_epi32(acc10, _mm256_madd_epi16(_mm256_maddubs_epi16(px, w), one16));
    acc01 = _mm256_add_epi32(acc01, _mm256_madd_epi16(_mm256_maddubs_epi16(px, o), _mm256_set1_epi16(short(v))));
  }
  m10 = HorizontalSum(acc10);
  m01 = HorizontalSum(acc01);
}

}  // namespace mvkp::internal
