// Inner loops of the detector, in a scalar reference and an AVX2 version
// (detector_avx2.cc, compiled with -mavx2 -mfma) chosen at run time.
// Both give identical results (tested).
#pragma once

#include <cstdint>
#include <vector>

namespace mvkp::internal {

// Columns x in [x0, x1) of row `c` that are local maxima over 3x3 (strictly
// greater than the previous row and the left neighbour, not smaller than the
// next row and the right neighbour, so plateaus give one point) and >= thresh.
// Appends them to `out` in increasing order.
using NmsRowFn = void (*)(const float* up, const float* c, const float* dn, int x0, int x1, float thresh,
                          std::vector<int>& out);
void NmsRowScalar(const float* up, const float* c, const float* dn, int x0, int x1, float thresh, std::vector<int>& out);
void NmsRowAvx2(const float* up, const float* c, const float* dn, int x0, int x1, float thresh, std::vector<int>& out);
NmsRowFn BestNmsRow();

// The largest of init and row[x] for x in [x0, x1) (only where mask[x] != 0
// if mask is not null): the per-cell maxima of the response. Values are not
// NaN, so the order of the comparisons does not matter.
using RowMaxFn = float (*)(const float* row, const std::uint8_t* mask, int x0, int x1, float init);
float RowMaxScalar(const float* row, const std::uint8_t* mask, int x0, int x1, float init);
float RowMaxAvx2(const float* row, const std::uint8_t* mask, int x0, int x1, float init);
RowMaxFn BestRowMax();

// One output row of the 3x3 structure tensor's smaller eigenvalue from the
// three rows of column-summed gradient products (see MinEigen3x3):
// out[x] = (A + C) - sqrt((A - C)^2 + B^2) with A, C = half the summed
// xx / yy products, B the summed xy products, all scaled by s2.
using EigenRowFn = void (*)(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1,
                            const float* b2, const float* c0, const float* c1, const float* c2, int x0, int x1, float s2,
                            float* out);
void EigenRowScalar(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1, const float* b2,
                    const float* c0, const float* c1, const float* c2, int x0, int x1, float s2, float* out);
void EigenRowAvx2(const float* a0, const float* a1, const float* a2, const float* b0, const float* b1, const float* b2,
                  const float* c0, const float* c1, const float* c2, int x0, int x1, float s2, float* out);
EigenRowFn BestEigenRow();

// Sobel gradients of one row (b, with neighbours a above and c below) and
// their products summed over three columns: hxx/hxy/hyy[x] for x in [2, W-2).
// Scratch rows pxx, pxy, pyy hold W floats each.
using GradientRowFn = void (*)(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx,
                               float* pxy, float* pyy, float* hxx, float* hxy, float* hyy);
void GradientRowScalar(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx, float* pxy,
                       float* pyy, float* hxx, float* hxy, float* hyy);
void GradientRowAvx2(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int W, float* pxx, float* pxy,
                     float* pyy, float* hxx, float* hxy, float* hyy);
GradientRowFn BestGradientRow();

}  // namespace mvkp::internal
