#include "mvkp/describe/internal/orient_kernels.h"

#include <cmath>
#include <cstdlib>

#include "mvkp/core/internal/cpu.h"

namespace mvkp::internal {

DiscTable::DiscTable(int radius) : r(radius), umax(std::size_t(radius) + 1) {
  for (int v = 0; v <= r; ++v) umax[v] = int(std::floor(std::sqrt(double(r * r - v * v)) + 0.5));
  if (r > kMaxSimdRadius) return;
  ones.assign(std::size_t(2 * r + 1) * 32, 0);
  weights.assign(ones.size(), 0);
  for (int v = -r; v <= r; ++v) {
    const int w = umax[std::abs(v)];
    for (int u = -w; u <= w; ++u) {
      const std::size_t k = std::size_t(v + r) * 32 + std::size_t(u + 15);
      ones[k] = 1;
      weights[k] = std::int8_t(u);
    }
  }
}

void DiscMomentsScalar(const std::uint8_t* centre, std::ptrdiff_t step, const DiscTable& t, std::int64_t& m10,
                       std::int64_t& m01) {
  std::int64_t a = 0, b = 0;
  for (int v = -t.r; v <= t.r; ++v) {
    const std::uint8_t* row = centre + v * step;
    const int w = t.umax[std::abs(v)];
    int sum = 0, wsum = 0;
    for (int u = -w; u <= w; ++u) {
      const int val = row[u];
      sum += val;
      wsum += u * val;
    }
    a += wsum;
    b += std::int64_t(v) * sum;
  }
  m10 = a;
  m01 = b;
}

DiscMomentsFn DiscMomentsSimd() { return CpuHasAvx2() ? DiscMomentsAvx2 : nullptr; }

void BilinearRow8Scalar(const float* img, std::ptrdiff_t stride, float cx, float cy, float c, float s,
                        const float* offs, float oy, float* out) {
  for (int j = 0; j < 8; ++j) {
    const float ox = offs[j];
    const float x = cx + c * ox - s * oy, y = cy + s * ox + c * oy;
    const int x0 = int(x), y0 = int(y);
    const float fx = x - float(x0), fy = y - float(y0);
    const float* r0 = img + std::ptrdiff_t(y0) * stride + x0;
    const float* r1 = r0 + stride;
    out[j] = (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
  }
}

BilinearRow8Fn BestBilinearRow8() { return CpuHasAvx2() ? BilinearRow8Avx2 : BilinearRow8Scalar; }

}  // namespace mvkp::internal
