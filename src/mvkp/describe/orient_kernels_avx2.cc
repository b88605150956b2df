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

void BilinearRow8Avx2(const float* img, std::ptrdiff_t stride, float cx, float cy, float c, float s,
                      const float* offs, float oy, float* out) {
  const __m256 ox = _mm256_loadu_ps(offs);
  const __m256 vc = _mm256_set1_ps(c), vs = _mm256_set1_ps(s);
  const __m256 soy = _mm256_set1_ps(s * oy), coy = _mm256_set1_ps(c * oy);
  const __m256 x = _mm256_sub_ps(_mm256_add_ps(_mm256_set1_ps(cx), _mm256_mul_ps(vc, ox)), soy);
  const __m256 y = _mm256_add_ps(_mm256_add_ps(_mm256_set1_ps(cy), _mm256_mul_ps(vs, ox)), coy);
  const __m256i x0 = _mm256_cvttps_epi32(x), y0 = _mm256_cvttps_epi32(y);
  const __m256 fx = _mm256_sub_ps(x, _mm256_cvtepi32_ps(x0)), fy = _mm256_sub_ps(y, _mm256_cvtepi32_ps(y0));
  const __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(y0, _mm256_set1_epi32(int(stride))), x0);
  const __m256i one = _mm256_set1_epi32(1), down = _mm256_set1_epi32(int(stride));
  const __m256 i00 = _mm256_i32gather_ps(img, idx, 4);
  const __m256 i01 = _mm256_i32gather_ps(img, _mm256_add_epi32(idx, one), 4);
  const __m256 i10 = _mm256_i32gather_ps(img, _mm256_add_epi32(idx, down), 4);
  const __m256 i11 = _mm256_i32gather_ps(img, _mm256_add_epi32(_mm256_add_epi32(idx, down), one), 4);
  const __m256 ones = _mm256_set1_ps(1.f);
  const __m256 gx = _mm256_sub_ps(ones, fx), gy = _mm256_sub_ps(ones, fy);
  const __m256 top = _mm256_add_ps(_mm256_mul_ps(gx, i00), _mm256_mul_ps(fx, i01));
  const __m256 bottom = _mm256_add_ps(_mm256_mul_ps(gx, i10), _mm256_mul_ps(fx, i11));
  _mm256_storeu_ps(out, _mm256_add_ps(_mm256_mul_ps(gy, top), _mm256_mul_ps(fy, bottom)));
}

}  // namespace mvkp::internal
