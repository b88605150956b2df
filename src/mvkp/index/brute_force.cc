#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/index/internal/l2_kernels.h"
#include "mvkp/index/knn_index.h"

namespace mvkp {
namespace {

using internal::kLanes;

// Vectors are kept in blocks of 8, transposed, so that one block's distances
// to a query are dim fused multiply-adds on 8 lanes. The two-distinct search
// uses |x|^2 + |q|^2 - 2 x.q with precomputed norms and four queries per pass.
// Padding lanes have label -1 and norm +inf, so they never win.
class BruteForceIndex final : public KnnIndex {
 public:
  void Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) override {
    Require(dim >= 1, ErrorCode::kInvalidArgument, "index: dimension must be >= 1");
    internal::RequireFinite(data, n, dim, "index: database");
    n_ = n;
    dim_ = dim;
    nblocks_ = (n + kLanes - 1) / kLanes;
    blocks_.assign(nblocks_ * std::size_t(dim) * kLanes, 1e18f);
    labels_.assign(nblocks_ * kLanes, -1);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t b = i / kLanes, l = i % kLanes;
      for (int d = 0; d < dim; ++d) blocks_[(b * dim + d) * kLanes + l] = data[i * dim + d];
      labels_[i] = labels ? labels[i] : std::int32_t(i);
    }
    norms_.assign(nblocks_ * kLanes, std::numeric_limits<float>::infinity());
    for (std::size_t i = 0; i < n; ++i) norms_[i] = internal::SquaredNorm(data + i * dim, dim);
    kernel_ = internal::BestL2Blocks8();
    two_ = internal::BestTwoDistinctNorm();
  }

  std::size_t size() const override { return n_; }
  int dim() const override { return dim_; }
  std::string name() const override { return "brute"; }

  void Search(const float* q, int k, Neighbor* out) const override {
    if (k <= 0) return;
    internal::RequireFinite(q, 1, dim_, "index: query");
    computations_.fetch_add(n_, std::memory_order_relaxed);
    thread_local std::vector<float> scratch;
    scratch.resize(nblocks_ * kLanes);
    SearchOne(q, k, out, scratch.data());
  }

  // The same answers as Search() query by query; the checks, the statistics
  // and the scratch buffer are paid once per batch (the IVF's coarse
  // quantiser asks for the lists of a whole frame's descriptors at once).
  void SearchBatch(const float* queries, std::size_t nq, int k, Neighbor* out) const override {
    if (k <= 0 || nq == 0) return;
    internal::RequireFinite(queries, nq, dim_, "index: query");
    computations_.fetch_add(n_ * nq, std::memory_order_relaxed);
    std::vector<float> scratch(nblocks_ * kLanes);
    for (std::size_t i = 0; i < nq; ++i)
      SearchOne(queries + i * std::size_t(dim_), k, out + i * std::size_t(k), scratch.data());
  }

  void SearchTwoDistinct(const float* q, Neighbor out[2], float ratio) const override {
    SearchTwoDistinctBatch(q, 1, out, ratio);
  }

  // Four queries per pass over the data: each stored row is loaded once for all four.
  void SearchTwoDistinctBatch(const float* queries, std::size_t nq, Neighbor* out, float ratio) const override {
    for (std::size_t first = 0; first < nq; first += 4) {
      const int m = int(std::min<std::size_t>(4, nq - first));
      const float* q = queries + first * std::size_t(dim_);
      internal::RequireFinite(q, std::size_t(m), dim_, "index: query");
      computations_.fetch_add(n_ * std::size_t(m), std::memory_order_relaxed);
      internal::TopTwo t[4];
      float qn[4];
      for (int k = 0; k < m; ++k) {
        t[k] = internal::EmptyTopTwo(ratio);
        qn[k] = internal::SquaredNorm(q + std::size_t(k) * dim_, dim_);
      }
      if (n_ > 0) two_(blocks_.data(), norms_.data(), labels_.data(), nblocks_, q, qn, m, dim_, t);
      for (int k = 0; k < m; ++k) {
        Neighbor* o = out + 2 * (first + k);
        o[0] = t[k].id1 < 0 ? Neighbor{} : Neighbor{t[k].id1, t[k].lab1, t[k].d1};
        o[1] = t[k].id2 < 0 ? Neighbor{} : Neighbor{t[k].id2, t[k].lab2, t[k].d2};
      }
    }
  }

 std::uint64_t distance_computations() const override { return computations_.load(); }
  void ResetStats() const override { computations_ = 0; }
  std::size_t memory_bytes() const override {
    return sizeof(*this) + blocks_.size() * sizeof(float) + norms_.size() * sizeof(float) +
           labels_.size() * sizeof(std::int32_t);
  }

 private:
  // The k nearest of q, nearest first, ties by row (the first stored wins);
  // `dist` is scratch for nblocks_ * kLanes distances (the caller's, so that
  // concurrent searches on one index are safe).
  void SearchOne(const float* q, int k, Neighbor* out, float* dist) const {
    std::fill(out, out + k, Neighbor{});
    if (n_ == 0) return;
    kernel_(blocks_.data(), nblocks_, q, dim_, dist);
    for (std::size_t i = 0; i < n_; ++i) {
      const float d = dist[i];
      if (d >= out[k - 1].distance) continue;
      int p = k - 1;
      while (p > 0 && out[p - 1].distance > d) {
        out[p] = out[p - 1];
        --p;
      }
      out[p] = {std::int32_t(i), labels_[i], d};
    }
  }

  std::size_t n_ = 0, nblocks_ = 0;
  int dim_ = 0;
  std::vector<float> blocks_;
  std::vector<float> norms_;  // |x|^2 per lane, +inf for padding
  std::vector<std::int32_t> labels_;
  internal::L2Blocks8Fn kernel_ = nullptr;
  internal::TwoDistinctNormFn two_ = nullptr;
  mutable std::atomic<std::uint64_t> computations_{0};
};

}  // namespace

std::unique_ptr<KnnIndex> MakeBruteForceIndex() { return std::make_unique<BruteForceIndex>(); }

}  // namespace mvkp
