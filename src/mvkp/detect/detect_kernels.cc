#include "mvkp/detect/internal/detect_kernels.h"

#include "detect_kernels_impl.h"

namespace mvkp::internal {

void NmsRowScalar(const float* up, const float* c, const float* dn, int x0, int x1, float thresh, std::vector<int>& out) {
  for (int x = x0; x < x1; ++x) {
    const float v = c[x];
    if (v < thresh) continue;
    if (v > c[x - 1] && v >= c[x + 1] && v > up[x - 1] && v > up[x] && v > up[x + 1] && v >= dn[x - 1] && v >= dn[x] &&
        v >= dn[x + 1])
      out.push_back(x);
  }
}

float RowMaxScalar(const float* row, const std::uint8_t* mask, int x0, int x1, float init) {
  float v = init;
  if (mask) {
    for (int x = x0; x < x1; ++x)
      if (mask[x] && row[x] > v) v = row[x];
  } else {
    for (int x = x0; x < x1; ++x) v = row[x] > v ? row[x] : v;
  }
  return v;
}

void EigenRowScalar(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1, const float* b2,
                    const float* c0, const float* c1, const float* c2, int x0, int x1, float s2, float* out) {
  impl::EigenRow(a0, a1, a2, b0, b1, b2, c0, c1, c2, x0, x1, s2, out);
}

void GradientRowScalar(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx, float* pxy,
                       float* pyy, float* hxx, float* hxy, float* hyy) {
  impl::GradientRow(a, b, c, W, pxx, pxy, pyy, hxx, hxy, hyy);
}

namespace {
bool HasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  }();
  return has;
}
}  // namespace

RowMaxFn BestRowMax() { return HasAvx2() ? RowMaxAvx2 : RowMaxScalar; }
NmsRowFn BestNmsRow() { return HasAvx2() ? NmsRowAvx2 : NmsRowScalar; }
EigenRowFn BestEigenRow() { return HasAvx2() ? EigenRowAvx2 : EigenRowScalar; }
GradientRowFn BestGradientRow() { return HasAvx2() ? GradientRowAvx2 : GradientRowScalar; }

}  // namespace mvkp::internal
