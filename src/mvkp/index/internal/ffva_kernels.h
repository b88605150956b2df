// FFVA filter and refinement kernels. Internal to mvkp_index.
//
// Codes: 4-bit cell numbers, 32 vectors per block, two dimensions per byte:
// block[p * 32 + lane] = code(lane, 2p) | code(lane, 2p + 1) << 4, for the
// npairs = ceil(dim / 2) pairs (an odd dim pads the last high nibble with 0).
// Tables: luts[j * 16 + c] is the byte bound of dimension j for cell c, for
// 2 * npairs dimensions (the padding dimension's table is all zero).
#pragma once

#include <cstddef>
#include <cstdint>

namespace mvkp::internal {

constexpr int kBlockLanes = 32;

// sums[b * 32 + lane] = saturating (at 255) sum over dimensions of
// luts[j * 16 + code(lane, j)], for nblocks consecutive blocks.
void FastScanSumsScalar(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                        std::uint8_t* sums);
void FastScanSumsAvx2(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                      std::uint8_t* sums);

// masks[b]: bit `lane` set when that lane's sum (as above) is <= thr, and the
// sums of those lanes. Sums of lanes whose bit is clear are unspecified: the
// SIMD kernel stops adding once no lane of a block can pass.
void FastScanMasksScalar(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                         std::uint8_t thr, std::uint8_t* sums, std::uint32_t* masks);
void FastScanMasksAvx2(const std::uint8_t* codes, std::size_t nblocks, int npairs, const std::uint8_t* luts,
                       std::uint8_t thr, std::uint8_t* sums, std::uint32_t* masks);

// Squared distance accumulated with one fused multiply-add per dimension, in
// dimension order: bit-identical to a lane of L2Blocks8 (brute force Search).
// The index computes exact distances with L2Blocks8 itself; these are the
// one-vector reference the tests hold it to.
float L2SequentialScalar(const float* x, const float* q, int dim);
float L2SequentialFma(const float* x, const float* q, int dim);  // needs FMA

// Per-query tables. `cells` holds, per dimension, the 17 cell boundaries
// -inf, e_0 .. e_14, +inf (cell c = [cells[c], cells[c+1])). bound[j*16 + c]
// = shrink * gap^2, gap = max(0, cells[c] - q_j, q_j - cells[c+1]): a lower
// bound of (v_j - q_j)^2 for every v_j in cell c. Rows j >= dim up to
// `rows` are zero.
void GapTablesScalar(const float* cells, const float* q, int dim, int rows, float shrink, float* bound);
void GapTablesAvx2(const float* cells, const float* q, int dim, int rows, float shrink, float* bound);
// lut[i] = min(255, floor(bound[i] * inv_scale)) for i < count (a multiple of 16; bound >= 0).
void QuantiseScalar(const float* bound, std::size_t count, float inv_scale, std::uint8_t* lut);
void QuantiseAvx2(const float* bound, std::size_t count, float inv_scale, std::uint8_t* lut);

struct FfvaKernels {
  void (*gap_tables)(const float*, const float*, int, int, float, float*);
  void (*quantise)(const float*, std::size_t, float, std::uint8_t*);
  void (*scan)(const std::uint8_t*, std::size_t, int, const std::uint8_t*, std::uint8_t, std::uint8_t*,
               std::uint32_t*);
  float (*box)(const float*, const float*, const float*, int);
};
// AVX2 kernels when the CPU has AVX2+FMA, else the scalar references.
const FfvaKernels& BestFfvaKernels();

// Squared distance from q to the box [lo, hi] (per dimension the gap
// max(0, lo - q, q - hi), squared and summed). Summation order differs between
// the two, so they agree exactly only where every term is exact (integers).
float BoxDistanceScalar(const float* lo, const float* hi, const float* q, int dim);
float BoxDistanceAvx2(const float* lo, const float* hi, const float* q, int dim);

}  // namespace mvkp::internal
