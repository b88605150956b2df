// mvkp's exact brute-force index, used two ways: the 2-distinct search the
// matcher runs (labels = vector ids, so it is plain 2-NN) and k-NN Search.
#include <algorithm>
#include <numeric>

#include "methods.h"
#include "mvkp/index/knn_index.h"

namespace mvkp::bench {
namespace {

class MvkpBrute : public Method {
 public:
  explicit MvkpBrute(bool two_distinct) : two_distinct_(two_distinct) {}

  void Build(const float* data, std::size_t n, int dim) override {
    index_ = MakeBruteForceIndex();
    std::vector<std::int32_t> labels(n);
    std::iota(labels.begin(), labels.end(), 0);
    index_->Build(data, n, dim, labels.data());
    n_ = n;
    dim_ = dim;
  }

  void SearchOne(const float* q, int k, std::int64_t* ids, float* dists) override {
    if (two_distinct_) {
      Neighbor nb[2];
      index_->SearchTwoDistinct(q, nb);
      Copy(nb, 2, k, ids, dists);
    } else {
      scratch_.resize(std::size_t(k));
      index_->Search(q, k, scratch_.data());
      Copy(scratch_.data(), k, k, ids, dists);
    }
  }

  bool has_batch() const override { return two_distinct_; }
  void SearchBatch(const float* q, std::size_t nq, int k, std::int64_t* ids, float* dists) override {
    scratch_.resize(2 * nq);
    index_->SearchTwoDistinctBatch(q, nq, scratch_.data());
    for (std::size_t i = 0; i < nq; ++i) Copy(&scratch_[2 * i], 2, k, ids + i * k, dists + i * k);
  }

  int max_k() const override { return two_distinct_ ? 2 : 0; }

  // Layout of brute_force.cc: rows padded to a multiple of 8, dim floats plus
  // a float norm and an int32 label per row.
  double StructureBytes() const override {
    const std::size_t rows = (n_ + 7) / 8 * 8;
    return double(rows) * (4.0 * dim_ + 4.0 + 4.0);
  }

 private:
  static void Copy(const Neighbor* nb, int have, int k, std::int64_t* ids, float* dists) {
    for (int i = 0; i < k; ++i) {
      ids[i] = i < have ? nb[i].id : -1;
      dists[i] = i < have ? nb[i].distance : -1.f;
    }
  }

  bool two_distinct_;
  std::unique_ptr<KnnIndex> index_;
  std::vector<Neighbor> scratch_;
  std::size_t n_ = 0;
  int dim_ = 0;
};

}  // namespace

void AddMvkpMethods(std::vector<MethodInfo>& out) {
  const std::string how = "padded rows x (4*dim + 4 norm + 4 label) bytes, per brute_force.cc";
  out.push_back({"mvkp-brute-2nn", "SearchTwoDistinct, labels = ids (exact)", how,
                 [] { return std::make_unique<MvkpBrute>(true); }});
  out.push_back({"mvkp-brute-knn", "Search(k) (exact)", how, [] { return std::make_unique<MvkpBrute>(false); }});
}

}  // namespace mvkp::bench
