#include <cmath>

#include "mvkp/index/internal/ffva_kernels.h"
#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp::internal {

void FastScanSumsScalar(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                        std::uint8_t* sums) {
  for (std::size_t b = 0; b < nblocks; ++b) {
    const std::uint8_t* blk = codes + b * std::size_t(npairs) * kBlockLanes;
    for (int lane = 0; lane < kBlockLanes; ++lane) {
      int acc = 0;
      for (int p = 0; p < npairs; ++p) {
        const std::uint8_t c = blk[p * kBlockLanes + lane];
        acc = std::min(255, acc + luts[(2 * p) * 16 + (c & 15)]);
        acc = std::min(255, acc + luts[(2 * p + 1) * 16 + (c >> 4)]);
      }
      sums[b * kBlockLanes + lane] = std::uint8_t(acc);
    }
  }
}

void FastScanMasksScalar(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                         std::uint8_t thr, std::uint8_t* sums, std::uint32_t* masks) {
  FastScanSumsScalar(codes, nblocks, npairs, luts, sums);
  for (std::size_t b = 0; b < nblocks; ++b) {
    std::uint32_t m = 0;
    for (int lane = 0; lane < kBlockLanes; ++lane)
      if (sums[b * kBlockLanes + lane] <= thr) m |= 1u << lane;
    masks[b] = m;
  }
}

float L2SequentialScalar(const float* x, const float* q, int dim) {
  float acc = 0.f;
  for (int d = 0; d < dim; ++d) {
    const float diff = x[d] - q[d];
    acc = std::fma(diff, diff, acc);
  }
  return acc;
}

float BoxDistanceScalar(const float* lo, const float* hi, const float* q, int dim) {
  float acc = 0.f;
  for (int d = 0; d < dim; ++d) {
    const float g = std::max(0.f, std::max(lo[d] - q[d], q[d] - hi[d]));
    acc += g * g;
  }
  return acc;
}

void GapTablesScalar(const float* cells, const float* q, int dim, int rows, float shrink, float* bound) {
  for (int j = 0; j < rows; ++j)
    for (int c = 0; c < 16; ++c) {
      float v = 0.f;
      if (j < dim) {
        const float* e = cells + std::size_t(j) * 17;
        const float gap = std::max(0.f, std::max(e[c] - q[j], q[j] - e[c + 1]));
        v = gap * gap * shrink;
      }
      bound[j * 16 + c] = v;
    }
}

void QuantiseScalar(const float* bound, std::size_t count, float inv_scale, std::uint8_t* lut) {
  for (std::size_t i = 0; i < count; ++i) {
    const float u = std::min(bound[i] * inv_scale, 255.f);
    lut[i] = std::uint8_t(int(u));
  }
}

const FfvaKernels& BestFfvaKernels() {
  static const FfvaKernels k = CpuHasAvx2()
                                   ? FfvaKernels{&GapTablesAvx2, &QuantiseAvx2, &FastScanMasksAvx2, &BoxDistanceAvx2}
                                   : FfvaKernels{&GapTablesScalar, &QuantiseScalar, &FastScanMasksScalar,
                                                 &BoxDistanceScalar};
  return k;
}

}  // namespace mvkp::internal
