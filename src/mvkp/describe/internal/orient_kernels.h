// Intensity-centroid moments over a disc, the inner loop of the describer's
// orientation (features.cc), in a scalar reference and an AVX2 version
// (orient_kernels_avx2.cc, compiled with -mavx2) chosen at run time. Both are
// exact integer sums, so they agree bit for bit (tested).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mvkp::internal {

// The disc of radius r: row v (|v| <= r) spans columns |u| <= umax[|v|].
struct DiscTable {
  explicit DiscTable(int radius);
  int r;
  std::vector<int> umax;  // r + 1 entries
  // For the AVX2 kernel (r <= kMaxSimdRadius): per row v + r, 32 signed bytes
  // for u = -15..16, 1 (ones) or u (weights) inside the disc and 0 outside.
  std::vector<std::int8_t> ones, weights;
};

inline constexpr int kMaxSimdRadius = 15;

// m10 = sum u * I(px + u, py + v), m01 = sum v * I(...) over the disc;
// `centre` points at pixel (px, py) of an 8-bit image with row step `step`.
// The disc must lie inside the image. The AVX2 version needs r <=
// kMaxSimdRadius and reads columns px - 15 .. px + 16 of each row, which must
// lie inside the image as well.
using DiscMomentsFn = void (*)(const std::uint8_t* centre, std::ptrdiff_t step, const DiscTable& t, std::int64_t& m10,
                               std::int64_t& m01);
void DiscMomentsScalar(const std::uint8_t* centre, std::ptrdiff_t step, const DiscTable& t, std::int64_t& m10,
                       std::int64_t& m01);
void DiscMomentsAvx2(const std::uint8_t* centre, std::ptrdiff_t step, const DiscTable& t, std::int64_t& m10,
                     std::int64_t& m01);
// The AVX2 kernel when the CPU has AVX2, else null.
DiscMomentsFn DiscMomentsSimd();

// One row of the describer's 8 x 8 grid of rotated samples: for lane j,
// x = (cx + c * offs[j]) - s * oy and y = (cy + s * offs[j]) + c * oy, and
// out[j] the bilinear interpolation of the float image `img` (row stride
// `stride` floats) at (x, y): (1 - fy) * ((1 - fx) * I00 + fx * I01) +
// fy * ((1 - fx) * I10 + fx * I11). Every sample must satisfy 0 <= x <
// cols - 2 and 0 <= y < rows - 2. The AVX2 version gathers eight samples at
// once with the same float operations in the same order (its file is
// compiled without contraction into fused multiply-adds), so both agree bit
// for bit (tested).
void BilinearRow8Scalar(const float* img, std::ptrdiff_t stride, float cx, float cy, float c, float s,
                        const float* offs, float oy, float* out);
void BilinearRow8Avx2(const float* img, std::ptrdiff_t stride, float cx, float cy, float c, float s,
                      const float* offs, float oy, float* out);
using BilinearRow8Fn = void (*)(const float*, std::ptrdiff_t, float, float, float, float, const float*, float, float*);
// The AVX2 kernel when the CPU has AVX2, else the scalar one.
BilinearRow8Fn BestBilinearRow8();

}  // namespace mvkp::internal
