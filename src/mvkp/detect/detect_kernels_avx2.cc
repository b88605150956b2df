// AVX2 builds of the detector's inner loops (compiled with -mavx2 -mfma
// -ffp-contract=off): the eigenvalue rows are the shared loop bodies,
// auto-vectorised 8 wide; the 3x3 maximum test is written with intrinsics.
#include <immintrin.h>

#include "mvkp/detect/internal/detect_kernels.h"

#include "detect_kernels_impl.h"

namespace mvkp::internal {

void NmsRowAvx2(const float* up, const float* c, const float* dn, int x0, int x1, float thresh, std::vector<int>& out) {
  const __m256 th = _mm256_set1_ps(thresh);
  int x = x0;
  for (; x + 8 <= x1; x += 8) {
    const __m256 v = _mm256_loadu_ps(c + x);
    __m256 m = _mm256_cmp_ps(v, th, _CMP_GE_OQ);
    if (_mm256_movemask_ps(m) == 0) continue;
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(c + x - 1), _CMP_GT_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(c + x + 1), _CMP_GE_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(up + x - 1), _CMP_GT_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(up + x), _CMP_GT_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(up + x + 1), _CMP_GT_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(dn + x - 1), _CMP_GE_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(dn + x), _CMP_GE_OQ));
    m = _mm256_and_ps(m, _mm256_cmp_ps(v, _mm256_loadu_ps(dn + x + 1), _CMP_GE_OQ));
    unsigned bits = unsigned(_mm256_movemask_ps(m));
    while (bits) {
      out.push_back(x + __builtin_ctz(bits));
      bits &= bits - 1;
    }
  }
  NmsRowScalar(up, c, dn, x, x1, thresh, out);
}

float RowMaxAvx2(const float* row, const std::uint8_t* mask, int x0, int x1, float init) {
  if (mask || x1 - x0 < 16) return RowMaxScalar(row, mask, x0, x1, init);
  __m256 a = _mm256_set1_ps(init), b = a;
  int x = x0;
  for (; x + 16 <= x1; x += 16) {
    a = _mm256_max_ps(a, _mm256_loadu_ps(row + x));
    b = _mm256_max_ps(b, _mm256_loadu_ps(row + x + 8));
  }
  a = _mm256_max_ps(a, b);
  __m128 m = _mm_max_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1));
  m = _mm_max_ps(m, _mm_movehl_ps(m, m));
  m = _mm_max_ss(m, _mm_shuffle_ps(m, m, 1));
  return RowMaxScalar(row, nullptr, x, x1, _mm_cvtss_f32(m));
}

void EigenRowAvx2(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1, const float* b2,
                  const float* c0, const float* c1, const float* c2, int x0, int x1, float s2, float* out) {
  impl::EigenRow(a0, a1, a2, b0, b1, b2, c0, c1, c2, x0, x1, s2, out);
}

namespace {
inline __m256i Load8(const std::uint8_t* p) {
  return _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p)));
}
}  // namespace

// Same arithmetic as impl::GradientRow (integer Sobel sums, exact float
// products and sums), 8 columns at a time.
void GradientRowAvx2(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx, float* pxy,
                     float* pyy, float* hxx, float* hxy, float* hyy) {
  int x = 1;
  for (; x + 8 + 1 <= W; x += 8) {
    const __m256i al = Load8(a + x - 1), am = Load8(a + x), ar = Load8(a + x + 1);
    const __m256i bl = Load8(b + x - 1), br = Load8(b + x + 1);
    const __m256i cl = Load8(c + x - 1), cm = Load8(c + x), cr = Load8(c + x + 1);
    const __m256i gxi = _mm256_add_epi32(_mm256_add_epi32(_mm256_sub_epi32(ar, al), _mm256_slli_epi32(_mm256_sub_epi32(br, bl), 1)),
                                         _mm256_sub_epi32(cr, cl));
    const __m256i gyi = _mm256_add_epi32(_mm256_add_epi32(_mm256_sub_epi32(cl, al), _mm256_slli_epi32(_mm256_sub_epi32(cm, am), 1)),
                                         _mm256_sub_epi32(cr, ar));
    const __m256 gx = _mm256_cvtepi32_ps(gxi), gy = _mm256_cvtepi32_ps(gyi);
    _mm256_storeu_ps(pxx + x, _mm256_mul_ps(gx, gx));
    _mm256_storeu_ps(pxy + x, _mm256_mul_ps(gx, gy));
    _mm256_storeu_ps(pyy + x, _mm256_mul_ps(gy, gy));
  }
  for (; x < W - 1; ++x) {
    const float gx = float((a[x + 1] - a[x - 1]) + 2 * (b[x + 1] - b[x - 1]) + (c[x + 1] - c[x - 1]));
    const float gy = float((c[x - 1] - a[x - 1]) + 2 * (c[x] - a[x]) + (c[x + 1] - a[x + 1]));
    pxx[x] = gx * gx;
    pxy[x] = gx * gy;
    pyy[x] = gy * gy;
  }
  x = 2;
  for (; x + 8 + 2 <= W; x += 8) {
    _mm256_storeu_ps(hxx + x, _mm256_add_ps(_mm256_add_ps(_mm256_loadu_ps(pxx + x - 1), _mm256_loadu_ps(pxx + x)),
                                            _mm256_loadu_ps(pxx + x + 1)));
    _mm256_storeu_ps(hxy + x, _mm256_add_ps(_mm256_add_ps(_mm256_loadu_ps(pxy + x - 1), _mm256_loadu_ps(pxy + x)),
                                            _mm256_loadu_ps(pxy + x + 1)));
    _mm256_storeu_ps(hyy + x, _mm256_add_ps(_mm256_add_ps(_mm256_loadu_ps(pyy + x - 1), _mm256_loadu_ps(pyy + x)),
                                            _mm256_loadu_ps(pyy + x + 1)));
  }
  for (; x < W - 2; ++x) {
    hxx[x] = pxx[x - 1] + pxx[x] + pxx[x + 1];
    hxy[x] = pxy[x - 1] + pxy[x] + pxy[x + 1];
    hyy[x] = pyy[x - 1] + pyy[x] + pyy[x + 1];
  }
}

}  // namespace mvkp::internal
