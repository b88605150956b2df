// Walsh–Hadamard kernel projection (thesis §3.1, SPEC §1).
//
// A k x k patch (k a power of two, 32 by default) is projected onto 2-D
// Walsh–Hadamard kernels K_(u,v)[y][x] = w_u[y] * w_v[x], where w_s is the
// 1-D Walsh function with s sign changes (sequency order). Kernels are taken in
// zig-zag order of increasing spatial frequency (by u+v, alternating
// direction); kernel 0 is DC. Every kernel has entries +-1 and squared norm
// k*k, so sum_i (c_i - c'_i)^2 / k^2 over any prefix of kernels is a lower
// bound of the squared Euclidean distance between the patches.
//
// Fast path: a Walsh function of sequency s < 2^j is constant on runs of
// k / 2^j samples and equals the 2^j-point Walsh function upsampled. So the
// first K kernels only ever need the n x n grid of block sums of the patch
// (n = the smallest power of two above the largest sequency used; n = 8 for
// K = 20), followed by a separable n-point transform of the sequencies used.
// That is about k*k additions plus a few hundred operations per patch, instead
// of K*k*k for direct projection or a full k*k-point transform.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mvkp::wht {

// 1-D sequency-ordered Walsh kernels of length n (a power of two): n rows of
// +-1 values, row s having exactly s sign changes.
std::vector<std::vector<int>> Walsh1D(int n);

// A 2-D kernel: u is the vertical (row) sequency, v the horizontal one.
struct Kernel {
  int u = 0;
  int v = 0;
};

// The first `count` 2-D kernels of a k x k patch in zig-zag order (DC first).
std::vector<Kernel> ZigZagOrder(int k, int count);

struct ProjectorOptions {
  int patch_size = 32;  // k, side of the square patch; a power of two, 4..256
  int dims = 20;        // K, number of kernels kept (SPEC: 8..100)
  bool drop_dc = true;  // skip kernel 0 (the patch mean) for lighting robustness
  void Check() const;   // throws mvkp::Error(kInvalidArgument)
};

class Projector {
 public:
  explicit Projector(const ProjectorOptions& options = {});

  int dims() const { return int(kernels_.size()); }
  int patch_size() const { return options_.patch_size; }
  // Side of the block-sum grid the kept kernels need (8 for the first 21 kernels).
  int grid() const { return grid_; }
  // Side of one block of the grid, in patch pixels: patch_size / grid.
  int block() const { return options_.patch_size / grid_; }
  const std::vector<Kernel>& kernels() const { return kernels_; }

  // Projects a patch_size x patch_size 8-bit patch (row stride in bytes) onto
  // the kept kernels: out[i] = <patch, kernel_i>, exactly, as integers.
  void Project(const std::uint8_t* patch, std::size_t stride, std::int32_t* out) const;

  // Projects from a grid() x grid() array of block sums (row-major). Equal to
  // Project() when grid holds the exact block sums of the patch; used by the
  // describer, which samples block sums directly from a box-filtered image.
  void ProjectGrid(const float* grid, float* out) const;

 private:
  ProjectorOptions options_;
  std::vector<Kernel> kernels_;
  int grid_ = 1;
  std::vector<int> walsh_;      // grid_ x grid_ sequency-ordered Walsh matrix
  std::vector<int> used_v_;     // distinct horizontal sequencies needed
  std::vector<int> v_slot_;     // kernel i -> index into used_v_
};

// Reference projection <patch, K_(u,v)> by a direct k*k-term sum, for tests.
std::int64_t ProjectDirect(const std::uint8_t* patch, std::size_t stride, int k, Kernel kernel);

}  // namespace mvkp::wht
