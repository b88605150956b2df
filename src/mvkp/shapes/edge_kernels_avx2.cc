// AVX2 build of EdgeTapsScalar (compiled with -mavx2 -ffp-contract=off; see
// CMakeLists.txt), reached only through BestEdgeTaps on CPUs that have AVX2.
// Eight outline samples per pass: the per-sample set-up in two groups of four
// doubles, the taps in eight floats. Every lane does the scalar version's
// operations in its order (no FMA), so the results are bit-identical.
#include <immintrin.h>

#include <algorithm>

#include "mvkp/shapes/internal/edge_kernels.h"

namespace mvkp::internal {

namespace {

// img[i] and img[i + 1] for eight indices, in lane order.
inline void Pairs(const float* img, __m256i i, __m256* left, __m256* right) {
  const double* base = reinterpret_cast<const double*>(img);
  // the masked form with a defined source: GCC 12's plain gather trips -Wmaybe-uninitialized
  const __m256d all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1)), zero = _mm256_setzero_pd();
  const __m256 lo = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero, base, _mm256_castsi256_si128(i), all, 4));
  const __m256 hi = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero, base, _mm256_extracti128_si256(i, 1), all, 4));
  // per 128-bit half: lanes (0 1 4 5) and (2 3 6 7); the 64-bit permute restores 0-7
  *left = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, 0x88)), 0xd8));
  *right = _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, 0xdd)), 0xd8));
}

// Bilinear samples at eight (x, y), all inside [0, width-1) x [0, height-1).
inline __m256 Bilinear(const float* img, __m256i step, __m256 x, __m256 y) {
  const __m256i x0 = _mm256_cvttps_epi32(x), y0 = _mm256_cvttps_epi32(y);
  const __m256 fx = _mm256_sub_ps(x, _mm256_cvtepi32_ps(x0)), fy = _mm256_sub_ps(y, _mm256_cvtepi32_ps(y0));
  const __m256i i00 = _mm256_add_epi32(_mm256_mullo_epi32(y0, step), x0);
  const __m256i i10 = _mm256_add_epi32(i00, step);
  // each lane's two neighbours in a row as one 8-byte gather element (half as
  // many gathered elements), then split into left and right
  __m256 r00, r01, r10, r11;
  Pairs(img, i00, &r00, &r01);
  Pairs(img, i10, &r10, &r11);
  const __m256 one = _mm256_set1_ps(1.f);
  const __m256 gx = _mm256_sub_ps(one, fx), gy = _mm256_sub_ps(one, fy);
  const __m256 top = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(r00, gx), _mm256_mul_ps(r01, fx)), gy);
  const __m256 bottom = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(r10, gx), _mm256_mul_ps(r11, fx)), fy);
  return _mm256_add_ps(top, bottom);
}

// Map(D, (x, y)) for four points, as the scalar Map.
inline void Map4(const double* H, __m256d x, __m256d y, __m256d* ox, __m256d* oy) {
  auto c = [&](int i) { return _mm256_set1_pd(H[i]); };
  const __m256d w = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(c(6), x), _mm256_mul_pd(c(7), y)), c(8));
  const __m256d absw = _mm256_andnot_pd(_mm256_set1_pd(-0.0), w);
  const __m256d big = _mm256_cmp_pd(absw, _mm256_set1_pd(1e-12), _CMP_GT_OQ);
  const __m256d iw = _mm256_blendv_pd(_mm256_set1_pd(1e12), _mm256_div_pd(_mm256_set1_pd(1.0), w), big);
  *ox = _mm256_mul_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(c(0), x), _mm256_mul_pd(c(1), y)), c(2)), iw);
  *oy = _mm256_mul_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(c(3), x), _mm256_mul_pd(c(4), y)), c(5)), iw);
}

// The set-up of four samples: mapped point, unit normal, window; lanes that
// are not scored get a harmless one-tap window at (2, 2) and valid = 0.
struct Setup4 {
  __m256d px, py, ux, uy, half, centre;
  __m128i steps;
  int valid;  // bit per lane
};

inline Setup4 SetUp(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                    const float* h) {
  const __m256d hd = _mm256_cvtps_pd(_mm_loadu_ps(h));
  const __m256d X = _mm256_add_pd(_mm256_cvtps_pd(_mm_loadu_ps(qx)), _mm256_mul_pd(_mm256_set1_pd(a.lean_x), hd));
  const __m256d Y = _mm256_add_pd(_mm256_cvtps_pd(_mm_loadu_ps(qy)), _mm256_mul_pd(_mm256_set1_pd(a.lean_y), hd));
  __m256d px, py, pnx, pny;
  Map4(a.D, X, Y, &px, &py);
  Map4(a.D, _mm256_add_pd(X, _mm256_cvtps_pd(_mm_loadu_ps(nx))), _mm256_add_pd(Y, _mm256_cvtps_pd(_mm_loadu_ps(ny))),
       &pnx, &pny);
  __m256d ux = _mm256_sub_pd(pnx, px), uy = _mm256_sub_pd(pny, py);
  const __m256d k = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(ux, ux), _mm256_mul_pd(uy, uy)));
  __m256d ok = _mm256_and_pd(_mm256_cmp_pd(k, _mm256_set1_pd(1e-6), _CMP_GT_OQ),
                             _mm256_cmp_pd(k, _mm256_set1_pd(100.0), _CMP_NGT_UQ));
  const __m256d inv = _mm256_div_pd(_mm256_set1_pd(1.0), k);
  ux = _mm256_mul_pd(ux, inv), uy = _mm256_mul_pd(uy, inv);
  // std::max(a, b) is (a < b ? b : a); the two only differ on NaN, and NaN lanes are not scored
  const __m256d ra = _mm256_mul_pd(_mm256_set1_pd(a.reach_px), k);
  const __m256d rb = _mm256_add_pd(_mm256_set1_pd(4.0), _mm256_mul_pd(_mm256_set1_pd(a.fit_search_px), k));
  const __m256d r = _mm256_add_pd(_mm256_blendv_pd(ra, rb, _mm256_cmp_pd(ra, rb, _CMP_LT_OQ)), _mm256_set1_pd(2.0));
  const __m256d zero = _mm256_setzero_pd();
  const __m256d W1 = _mm256_set1_pd(double(a.width - 1)), H1 = _mm256_set1_pd(double(a.height - 1));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_sub_pd(px, r), zero, _CMP_GE_OQ));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_sub_pd(py, r), zero, _CMP_GE_OQ));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_add_pd(px, r), W1, _CMP_LT_OQ));
  ok = _mm256_and_pd(ok, _mm256_cmp_pd(_mm256_add_pd(py, r), H1, _CMP_LT_OQ));
  Setup4 s;
  s.valid = _mm256_movemask_pd(ok);
  const __m256d half = _mm256_mul_pd(_mm256_set1_pd(a.search_px), k);
  // steps = half > 0 ? max(1, int(ceil(half))) : 0, where ceil(half) >= 1 already
  // (scored lanes: half <= search_px * 100)
  const __m256d pos = _mm256_and_pd(ok, _mm256_cmp_pd(half, zero, _CMP_GT_OQ));
  s.steps = _mm256_cvttpd_epi32(_mm256_blendv_pd(zero, _mm256_round_pd(half, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC), pos));
  // centre = offset == 0 ? 0 : copysign(max(|offset| * k, 4), offset)
  __m256d centre = zero;
  if (a.offset_px != 0) {
    const __m256d m = _mm256_mul_pd(_mm256_set1_pd(a.offset_px < 0 ? -a.offset_px : a.offset_px), k);
    const __m256d four = _mm256_set1_pd(4.0);
    centre = _mm256_blendv_pd(m, four, _mm256_cmp_pd(m, four, _CMP_LT_OQ));
    if (a.offset_px < 0) centre = _mm256_xor_pd(centre, _mm256_set1_pd(-0.0));
  }
  // lanes not scored: one tap at (2, 2) along a zero normal
  const __m256d two = _mm256_set1_pd(2.0);
  s.px = _mm256_blendv_pd(two, px, ok), s.py = _mm256_blendv_pd(two, py, ok);
  s.ux = _mm256_and_pd(ux, ok), s.uy = _mm256_and_pd(uy, ok);
  s.half = _mm256_and_pd(half, ok), s.centre = _mm256_and_pd(centre, ok);
  return s;
}

// Tap positions t = centre + (steps ? half * i / steps : 0) for four lanes
// (i and steps as int32), then the photo point p + u * t, as floats.
inline void Taps4(const Setup4& s, __m128i i, __m128 * x, __m128 * y) {
  const __m256d sd = _mm256_cvtepi32_pd(s.steps);
  __m256d q = _mm256_div_pd(_mm256_mul_pd(s.half, _mm256_cvtepi32_pd(i)), sd);
  q = _mm256_blendv_pd(q, _mm256_setzero_pd(), _mm256_cmp_pd(sd, _mm256_setzero_pd(), _CMP_EQ_OQ));
  const __m256d t = _mm256_add_pd(s.centre, q);
  *x = _mm256_cvtpd_ps(_mm256_add_pd(s.px, _mm256_mul_pd(s.ux, t)));
  *y = _mm256_cvtpd_ps(_mm256_add_pd(s.py, _mm256_mul_pd(s.uy, t)));
}

void Block8(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny, const float* h,
            float* best, int* valid) {
  const Setup4 lo = SetUp(a, qx, qy, nx, ny, h), hi = SetUp(a, qx + 4, qy + 4, nx + 4, ny + 4, h + 4);
  *valid = lo.valid | (hi.valid << 4);
  if (!*valid) {
    _mm256_storeu_ps(best, _mm256_setzero_ps());
    return;
  }
  const __m256 ux = _mm256_set_m128(_mm256_cvtpd_ps(hi.ux), _mm256_cvtpd_ps(lo.ux));
  const __m256 uy = _mm256_set_m128(_mm256_cvtpd_ps(hi.uy), _mm256_cvtpd_ps(lo.uy));
  const __m256i steps = _mm256_set_m128i(hi.steps, lo.steps);
  const __m256i span = _mm256_add_epi32(steps, steps);
  alignas(32) int st[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(st), span);
  const int jmax = *std::max_element(st, st + 8);
  const __m256i istep = _mm256_set1_epi32(int(a.step));
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 halfw = _mm256_set1_ps(0.5f);
  __m256 b = _mm256_setzero_ps();
  for (int j = 0; j <= jmax; ++j) {
    // tap i = min(j, 2 steps) - steps: lanes with fewer taps repeat their last (max is unchanged)
    const __m256i i = _mm256_sub_epi32(_mm256_min_epi32(_mm256_set1_epi32(j), span), steps);
    __m128 xl, yl, xh, yh;
    Taps4(lo, _mm256_castsi256_si128(i), &xl, &yl);
    Taps4(hi, _mm256_extracti128_si256(i, 1), &xh, &yh);
    const __m256 x = _mm256_set_m128(xh, xl), y = _mm256_set_m128(yh, yl);
    const __m256 A = Bilinear(a.image, istep, _mm256_add_ps(x, ux), _mm256_add_ps(y, uy));
    const __m256 B = Bilinear(a.image, istep, _mm256_sub_ps(x, ux), _mm256_sub_ps(y, uy));
    const __m256 g = _mm256_and_ps(_mm256_mul_ps(halfw, _mm256_sub_ps(A, B)), abs_mask);
    b = _mm256_max_ps(g, b);
  }
  // lanes not scored report 0
  const __m256i lane = _mm256_set_epi32(128, 64, 32, 16, 8, 4, 2, 1);
  const __m256i on = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(*valid), lane), lane);
  _mm256_storeu_ps(best, _mm256_and_ps(b, _mm256_castsi256_ps(on)));
}

}  // namespace

void EdgeTapsAvx2(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                  const float* h, int n, float* best, std::uint8_t* valid) {
  for (int i = 0; i < n; i += 8) {
    const int m = std::min(8, n - i);
    alignas(32) float b[8];
    int v = 0;
    if (m == 8) {
      Block8(a, qx + i, qy + i, nx + i, ny + i, h + i, b, &v);
    } else {  // the tail, padded with copies of its first sample
      float p[5][8];
      const float* src[5] = {qx + i, qy + i, nx + i, ny + i, h + i};
      for (int c = 0; c < 5; ++c)
        for (int l = 0; l < 8; ++l) p[c][l] = src[c][l < m ? l : 0];
      Block8(a, p[0], p[1], p[2], p[3], p[4], b, &v);
    }
    for (int l = 0; l < m; ++l) best[i + l] = b[l], valid[i + l] = std::uint8_t((v >> l) & 1);
  }
}

}  // namespace mvkp::internal
