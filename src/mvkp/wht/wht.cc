#include "mvkp/wht/wht.h"

#include <algorithm>
#include <string>

#include "mvkp/core/error.h"

namespace mvkp::wht {
namespace {

bool IsPow2(int n) { return n > 0 && (n & (n - 1)) == 0; }

int SignChanges(const std::vector<int>& row) {
  int c = 0;
  for (std::size_t i = 1; i < row.size(); ++i) c += row[i] != row[i - 1];
  return c;
}

}  // namespace

std::vector<std::vector<int>> Walsh1D(int n) {
  Require(IsPow2(n), ErrorCode::kInvalidArgument, "Walsh1D: length must be a power of two, got " + std::to_string(n));
  // Natural-order (Sylvester) Hadamard matrix, then sorted by sequency.
  std::vector<std::vector<int>> h(n, std::vector<int>(n));
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) h[r][c] = (__builtin_popcount(unsigned(r & c)) & 1) ? -1 : 1;
  std::vector<std::vector<int>> out(n);
  for (auto& row : h) out[SignChanges(row)] = row;  // sequencies are exactly 0..n-1
  return out;
}

std::vector<Kernel> ZigZagOrder(int k, int count) {
  std::vector<Kernel> out;
  for (int d = 0; d <= 2 * (k - 1) && int(out.size()) < count; ++d) {
    for (int t = 0; t <= d && int(out.size()) < count; ++t) {
      const int u = (d % 2 == 0) ? d - t : t;  // alternate direction per diagonal
      const int v = d - u;
      if (u < k && v < k) out.push_back({u, v});
    }
  }
  return out;
}

void ProjectorOptions::Check() const {
  Require(IsPow2(patch_size) && patch_size >= 4 && patch_size <= 256, ErrorCode::kInvalidArgument,
          "patch size must be a power of two in 4..256, got " + std::to_string(patch_size));
  const int max_dims = patch_size * patch_size - (drop_dc ? 1 : 0);
  Require(dims >= 1 && dims <= max_dims, ErrorCode::kInvalidArgument,
          "number of kernels must be in 1.." + std::to_string(max_dims) + ", got " + std::to_string(dims));
}

Projector::Projector(const ProjectorOptions& options) : options_(options) {
  options_.Check();
  const int k = options_.patch_size;
  const int skip = options_.drop_dc ? 1 : 0;
  auto all = ZigZagOrder(k, options_.dims + skip);
  kernels_.assign(all.begin() + skip, all.end());
  int max_seq = 0;
  for (const auto& kr : kernels_) max_seq = std::max({max_seq, kr.u, kr.v});
  grid_ = 1;
  while (grid_ <= max_seq) grid_ *= 2;
  const auto w = Walsh1D(grid_);
  walsh_.resize(std::size_t(grid_) * grid_);
  for (int s = 0; s < grid_; ++s)
    for (int x = 0; x < grid_; ++x) walsh_[std::size_t(s) * grid_ + x] = w[s][x];
  for (const auto& kr : kernels_) {
    auto it = std::find(used_v_.begin(), used_v_.end(), kr.v);
    if (it == used_v_.end()) {
      used_v_.push_back(kr.v);
      it = used_v_.end() - 1;
    }
    v_slot_.push_back(int(it - used_v_.begin()));
  }
}

void Projector::Project(const std::uint8_t* patch, std::size_t stride, std::int32_t* out) const {
  const int k = options_.patch_size, n = grid_, b = k / n;
  // Block sums: n x n, each over b x b pixels.
  std::int32_t small[16 * 16];
  std::vector<std::int32_t> large;
  std::int32_t* s = small;
  if (n > 16) {
    large.resize(std::size_t(n) * n);
    s = large.data();
  }
  std::fill(s, s + n * n, 0);
  for (int y = 0; y < k; ++y) {
    const std::uint8_t* row = patch + std::size_t(y) * stride;
    std::int32_t* srow = s + (y / b) * n;
    for (int x = 0; x < k; ++x) srow[x / b] += row[x];
  }
  // Rows: r[i][slot] = sum_j w_v[j] * s[i][j]
  const int nv = int(used_v_.size());
  std::int64_t rsmall[16 * 16];
  std::vector<std::int64_t> rlarge;
  std::int64_t* r = rsmall;
  if (n * nv > 16 * 16) {
    rlarge.resize(std::size_t(n) * nv);
    r = rlarge.data();
  }
  for (int i = 0; i < n; ++i)
    for (int t = 0; t < nv; ++t) {
      const int* w = &walsh_[std::size_t(used_v_[t]) * n];
      std::int64_t acc = 0;
      for (int j = 0; j < n; ++j) acc += std::int64_t(w[j]) * s[i * n + j];
      r[std::size_t(i) * nv + t] = acc;
    }
  for (std::size_t q = 0; q < kernels_.size(); ++q) {
    const int* w = &walsh_[std::size_t(kernels_[q].u) * n];
    std::int64_t acc = 0;
    for (int i = 0; i < n; ++i) acc += w[i] * r[std::size_t(i) * nv + v_slot_[q]];
    out[q] = std::int32_t(acc);
  }
}

void Projector::ProjectGrid(const float* g, float* out) const {
  const int n = grid_;
  const int nv = int(used_v_.size());
  float r[16 * 16 * 4];
  std::vector<float> heap;
  float* rp = r;
  if (n * nv > int(sizeof(r) / sizeof(float))) {
    heap.resize(std::size_t(n) * nv);
    rp = heap.data();
  }
  for (int i = 0; i < n; ++i)
    for (int t = 0; t < nv; ++t) {
      const int* w = &walsh_[std::size_t(used_v_[t]) * n];
      float acc = 0.f;
      for (int j = 0; j < n; ++j) acc += float(w[j]) * g[i * n + j];
      rp[i * nv + t] = acc;
    }
  for (std::size_t q = 0; q < kernels_.size(); ++q) {
    const int* w = &walsh_[std::size_t(kernels_[q].u) * n];
    float acc = 0.f;
    for (int i = 0; i < n; ++i) acc += float(w[i]) * rp[i * nv + v_slot_[q]];
    out[q] = acc;
  }
}

std::int64_t ProjectDirect(const std::uint8_t* patch, std::size_t stride, int k, Kernel kernel) {
  const auto w = Walsh1D(k);
  std::int64_t acc = 0;
  for (int y = 0; y < k; ++y)
    for (int x = 0; x < k; ++x) acc += std::int64_t(w[kernel.u][y]) * w[kernel.v][x] * patch[std::size_t(y) * stride + x];
  return acc;
}

}  // namespace mvkp::wht
