// The inner loop of EdgeEvidence::OnEdge (the outline-on-edge score), in a
// scalar reference and an AVX2 version (edge_kernels_avx2.cc, compiled with
// -mavx2 -ffp-contract=off) chosen at run time. The AVX2 version does the
// same IEEE operations in the same order, eight outline samples at a time,
// so both give bit-identical results (tested).
#pragma once

#include <cstddef>
#include <cstdint>

namespace mvkp::internal {

// What one OnEdge call scores its samples against.
struct EdgeTapArgs {
  const float* image = nullptr;  // the blurred grey photo, CV_32F
  std::ptrdiff_t step = 0;       // its row step, in floats
  float width = 0, height = 0;   // its size, px
  double D[9] = {};              // depth px -> photo px, row-major
  double lean_x = 0, lean_y = 0; // photo shift per metre of height (depth px)
  double offset_px = 0;          // where the window is centred, depth px along the normal (0: on the outline)
  double search_px = 0;          // the window's half width, depth px (0: one tap)
  double reach_px = 0;           // EdgeEvidenceOptions offset_px + search_px: what must fit in the photo
  double fit_search_px = 0;      // EdgeEvidenceOptions search_px (the same fit test for every call)
};

// For each of the n samples (depth point q, unit normal n, height h): the
// largest |central difference of the photo along the mapped normal| over the
// window's taps, in best[i], and valid[i] = 1 when the sample was scored (its
// mapped normal is sane and the whole reference window lies in the photo);
// valid[i] = 0 and best[i] = 0 otherwise.
using EdgeTapsFn = void (*)(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                            const float* h, int n, float* best, std::uint8_t* valid);
void EdgeTapsScalar(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                    const float* h, int n, float* best, std::uint8_t* valid);
void EdgeTapsAvx2(const EdgeTapArgs& a, const float* qx, const float* qy, const float* nx, const float* ny,
                  const float* h, int n, float* best, std::uint8_t* valid);
// AVX2 when the CPU has it and the photo's indices fit 32 bits, else scalar.
EdgeTapsFn BestEdgeTaps(const EdgeTapArgs& a);

}  // namespace mvkp::internal
