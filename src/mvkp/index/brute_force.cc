#include <algorithm>
#include <string>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/index/internal/l2_kernels.h"
#include "mvkp/index/knn_index.h"

namespace mvkp {
namespace {

using internal::kLanes;

// Vectors are kept in blocks of 8, transposed, so that one block's distances
// to a query are dim fused multiply-adds on 8 lanes. Padding lanes hold a huge
// value so they never win.
class BruteForceIndex final : public KnnIndex {
 public:
  void Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) override {
    Require(dim >= 1, ErrorCode::kInvalidArgument, "index: dimension must be >= 1");
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
    kernel_ = internal::BestL2Blocks8();
    two_ = internal::BestTwoDistinct();
  }

  std::size_t size() const override { return n_; }
  int dim() const override { return dim_; }
  std::string name() const override { return "brute"; }

  void Search(const float* q, int k, Neighbor* out) const override {
    std::fill(out, out + k, Neighbor{});
    if (n_ == 0 || k <= 0) return;
    const float* dist = Distances(q);
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

  void SearchTwoDistinct(const float* q, Neighbor out[2], float ratio) const override {
    internal::TopTwo t = internal::EmptyTopTwo(ratio);
    if (n_ > 0) two_(blocks_.data(), labels_.data(), nblocks_, q, dim_, 0, t);
    out[0] = t.id1 < 0 ? Neighbor{} : Neighbor{t.id1, t.lab1, t.d1};
    out[1] = t.id2 < 0 ? Neighbor{} : Neighbor{t.id2, t.lab2, t.d2};
  }

 private:
  // Distances from q to every stored vector, in a per-thread scratch buffer so
  // that concurrent searches on one index are safe.
  const float* Distances(const float* q) const {
    thread_local std::vector<float> scratch;
    scratch.resize(nblocks_ * kLanes);
    kernel_(blocks_.data(), nblocks_, q, dim_, scratch.data());
    return scratch.data();
  }

  std::size_t n_ = 0, nblocks_ = 0;
  int dim_ = 0;
  std::vector<float> blocks_;
  std::vector<std::int32_t> labels_;
  internal::L2Blocks8Fn kernel_ = nullptr;
  internal::TwoDistinctFn two_ = nullptr;
};

}  // namespace

std::unique_ptr<KnnIndex> MakeBruteForceIndex() { return std::make_unique<BruteForceIndex>(); }

}  // namespace mvkp
