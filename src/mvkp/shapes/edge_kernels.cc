#include "mvkp/shapes/internal/edge_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mvkp/core/internal/cpu.h"

namespace mvkp::internal {

namespace {

// Bilinear sample; the caller keeps (x, y) inside [0, width-1) x [0, height-1).
inline float At(const float* img, std::ptrdiff_t step, float x, float y) {
  const int x0 = int(x), y0 = int(y);
  const float fx = x - float(x0), fy = y - float(y0);
  const float* r0 = img + std::ptrdiff_t(y0) * step + x0;
  const float* r1 = r0 + step;
  return (r0[0] * (1 - fx) + r0[1] * fx) * (1 - fy) + (r1[0] * (1 - fx) + r1[1] * fx) * fy;
}

inline void Map(const double* H, double x, double y, double* ox, double* oy) {
  const double w = H[6] * x + H[7] * y + H[8];
  const double iw = std::abs(w) > 1e-12 ? 1.0 / w : 1e12;
  *ox = (H[0] * x + H[1] * y + H[2]) * iw;
  *oy = (H[3] * x + H[4] * y + H[5]) * iw;
}

}  // namespace

void EdgeTapsScalar(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                    const float* h, int n, float* best, std::uint8_t* valid) {
  const float w = a.width, hh = a.height;
  for (int si = 0; si < n; ++si) {
    best[si] = 0, valid[si] = 0;
    const double X = double(qx[si]) + a.lean_x * double(h[si]), Y = double(qy[si]) + a.lean_y * double(h[si]);
    double px, py, pnx, pny;
    Map(a.D, X, Y, &px, &py);
    Map(a.D, X + double(nx[si]), Y + double(ny[si]), &pnx, &pny);
    double ux = pnx - px, uy = pny - py;
    // image px per depth px (not std::hypot: glibc's took 14 % of a registration)
    const double k = std::sqrt(ux * ux + uy * uy);
    if (!(k > 1e-6) || k > 100) continue;
    const double inv = 1.0 / k;
    ux *= inv, uy *= inv;
    const double r = std::max(a.reach_px * k, 4.0 + a.fit_search_px * k) + 2;
    if (!(px - r >= 0 && py - r >= 0 && px + r < w - 1 && py + r < hh - 1)) continue;
    const double half = a.search_px * k;
    const int steps = half > 0 ? std::max(1, int(std::ceil(half))) : 0;
    // the reference stays clear of the edge's blur however coarse the photo
    const double centre =
        a.offset_px == 0 ? 0.0 : std::copysign(std::max(std::abs(a.offset_px) * k, 4.0), a.offset_px);
    const float fx = float(ux), fy = float(uy);
    float b = 0;
    for (int i = -steps; i <= steps; ++i) {
      const double t = centre + (steps ? half * i / steps : 0.0);
      const float x = float(px + ux * t), y = float(py + uy * t);
      const float g = 0.5f * (At(a.image, a.step, x + fx, y + fy) - At(a.image, a.step, x - fx, y - fy));
      b = std::max(b, std::abs(g));
    }
    best[si] = b, valid[si] = 1;
  }
}

EdgeTapsFn BestEdgeTaps(const EdgeTapArgs& a) {
  // the AVX2 gathers take 32-bit element indices
  const double last = double(a.step) * (double(a.height) + 1);
  return CpuHasAvx2() && last < double(std::numeric_limits<int>::max()) ? EdgeTapsAvx2 : EdgeTapsScalar;
}

}  // namespace mvkp::internal
