// Loop bodies shared by the scalar (detect_kernels.cc) and AVX2
// (detect_kernels_avx2.cc) builds of the eigenvalue kernels: the same source,
// compiled twice, so the two agree bit for bit (both files disable FMA
// contraction). Included only by those two files.
#pragma once

#include <cmath>
#include <cstdint>

namespace mvkp::internal::impl {

inline void GradientRow(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx,
                        float* pxy, float* pyy, float* hxx, float* hxy, float* hyy) {
  for (int x = 1; x < W - 1; ++x) {
    const float gx = float((a[x + 1] - a[x - 1]) + 2 * (b[x + 1] - b[x - 1]) + (c[x + 1] - c[x - 1]));
    const float gy = float((c[x - 1] - a[x - 1]) + 2 * (c[x] - a[x]) + (c[x + 1] - a[x + 1]));
    pxx[x] = gx * gx;
    pxy[x] = gx * gy;
    pyy[x] = gy * gy;
  }
  for (int x = 2; x < W - 2; ++x) {
    hxx[x] = pxx[x - 1] + pxx[x] + pxx[x + 1];
    hxy[x] = pxy[x - 1] + pxy[x] + pxy[x + 1];
    hyy[x] = pyy[x - 1] + pyy[x] + pyy[x + 1];
  }
}

inline void EigenRow(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1,
                     const float* b2, const float* c0, const float* c1, const float* c2, int x0, int x1, float s2,
                     float* out) {
  for (int x = x0; x < x1; ++x) {
    const float A = (a0[x] + a1[x] + a2[x]) * (0.5f * s2);
    const float B = (b0[x] + b1[x] + b2[x]) * s2;
    const float C = (c0[x] + c1[x] + c2[x]) * (0.5f * s2);
    out[x] = (A + C) - std::sqrt((A - C) * (A - C) + B * B);
  }
}

}  // namespace mvkp::internal::impl
