// mvkp's own indexes: the exact brute force and FFVA (exact, and with the
// thesis's approximate block distance), each used the way the matcher uses it
// (2-distinct search with labels = vector ids, so plain 2-NN) and as k-NN.
#include <algorithm>
#include <functional>
#include <numeric>

#include "methods.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/knn_index.h"

namespace mvkp::bench {
namespace {

enum class Query { kTwoDistinct, kKnn };

class MvkpMethod : public Method {
 public:
  MvkpMethod(std::function<std::unique_ptr<KnnIndex>()> make, Query query) : make_(std::move(make)), query_(query) {}

  void Build(const float* data, std::size_t n, int dim) override {
    index_.reset();
    index_ = make_();
    if (query_ == Query::kTwoDistinct) {  // labels = ids: plain 2-NN, as the matcher's search runs it
      std::vector<std::int32_t> labels(n);
      std::iota(labels.begin(), labels.end(), 0);
      index_->Build(data, n, dim, labels.data());
    } else {
      index_->Build(data, n, dim, nullptr);  // k-NN needs no labels (FFVA then stores none)
    }
  }

  void SearchOne(const float* q, int k, std::int64_t* ids, float* dists) override {
    if (query_ == Query::kTwoDistinct) {
      Neighbor nb[2];
      index_->SearchTwoDistinct(q, nb);
      Copy(nb, 2, k, ids, dists);
    } else {
      scratch_.resize(std::size_t(k));
      index_->Search(q, k, scratch_.data());
      Copy(scratch_.data(), k, k, ids, dists);
    }
  }

  bool has_batch() const override { return true; }
  void SearchBatch(const float* q, std::size_t nq, int k, std::int64_t* ids, float* dists) override {
    const std::size_t kk = std::size_t(k);
    if (query_ == Query::kTwoDistinct) {
      scratch_.resize(2 * nq);
      index_->SearchTwoDistinctBatch(q, nq, scratch_.data());
      for (std::size_t i = 0; i < nq; ++i) Copy(&scratch_[2 * i], 2, k, ids + i * kk, dists + i * kk);
    } else {
      scratch_.resize(kk * nq);
      index_->SearchBatch(q, nq, k, scratch_.data());
      for (std::size_t i = 0; i < nq; ++i) Copy(&scratch_[kk * i], k, k, ids + i * kk, dists + i * kk);
    }
  }

  int max_k() const override { return query_ == Query::kTwoDistinct ? 2 : 0; }

  double StructureBytes() const override { return double(index_->memory_bytes()); }

  void ResetDistanceCount() override { index_->ResetStats(); }
  double DistanceComputations(const float*, std::size_t, int) override {
    return double(index_->distance_computations());
  }

 private:
  static void Copy(const Neighbor* nb, int have, int k, std::int64_t* ids, float* dists) {
    for (int i = 0; i < k; ++i) {
      ids[i] = i < have ? nb[i].id : -1;
      dists[i] = i < have ? nb[i].distance : -1.f;
    }
  }

  std::function<std::unique_ptr<KnnIndex>()> make_;
  Query query_;
  std::unique_ptr<KnnIndex> index_;
  std::vector<Neighbor> scratch_;
};

std::unique_ptr<KnnIndex> MakeFfvaApprox() {
  FfvaOptions o;
  o.filter = FfvaOptions::Filter::kApprox;
  return MakeFfvaIndex(o);
}

}  // namespace

void AddMvkpMethods(std::vector<MethodInfo>& out) {
  const std::string how = "KnnIndex::memory_bytes() (the index's copy of the vectors included)";
  const std::string dist = "KnnIndex::distance_computations() over the single-query pass (ResetStats() before it)";
  auto add = [&](const char* name, std::string params, std::unique_ptr<KnnIndex> (*make)(), Query query) {
    out.push_back({name, std::move(params), how,
                   [make, query] { return std::make_unique<MvkpMethod>(make, query); }, dist});
  };
  const std::string leaf = "leaf_size=" + std::to_string(FfvaOptions{}.leaf_size);
  add("mvkp-brute-2nn", "MakeBruteForceIndex, SearchTwoDistinct, labels = ids (exact); batch: SearchTwoDistinctBatch",
      [] { return MakeBruteForceIndex(); }, Query::kTwoDistinct);
  add("mvkp-brute-knn", "MakeBruteForceIndex, Search(k) (exact); batch: SearchBatch",
      [] { return MakeBruteForceIndex(); }, Query::kKnn);
  add("mvkp-ffva-2nn",
      "MakeFfvaIndex " + leaf + ", SearchTwoDistinct, labels = ids (exact); batch: SearchTwoDistinctBatch",
      [] { return MakeFfvaIndex(); }, Query::kTwoDistinct);
  add("mvkp-ffva-knn", "MakeFfvaIndex " + leaf + ", Search(k) (exact); batch: SearchBatch",
      [] { return MakeFfvaIndex(); }, Query::kKnn);
  add("mvkp-ffva-approx", "MakeFfvaIndex filter=kApprox " + leaf + ", Search(k) (approximate); batch: SearchBatch",
      &MakeFfvaApprox, Query::kKnn);
}

}  // namespace mvkp::bench
