// hnswlib baseline: HierarchicalNSW<float> over L2Space. hnswlib.h defines
// non-inline functions, so it is included by this file only.
#include <hnswlib/hnswlib.h>

#include "methods.h"

namespace mvkp::bench {
namespace {

// Counts the calls of hnswlib's distance function. hnswlib's own
// metric_distance_computations adds the length of every neighbour list it
// scans, already visited neighbours included (whose distance it does not
// compute), so it overstates the work; the wrapper counts what is computed.
hnswlib::DISTFUNC<float> g_inner_distance = nullptr;
std::uint64_t g_distance_calls = 0;
float CountingDistance(const void* a, const void* b, const void* param) {
  ++g_distance_calls;
  return g_inner_distance(a, b, param);
}

class Hnswlib : public Method {
 public:
  static constexpr int kM = 16, kEfConstruction = 200, kEf = 64;
  void Build(const float* data, std::size_t n, int dim) override {
    index_.reset();
    space_ = std::make_unique<hnswlib::L2Space>(std::size_t(dim));
    index_ = std::make_unique<hnswlib::HierarchicalNSW<float>>(space_.get(), n, kM, kEfConstruction);
    for (std::size_t i = 0; i < n; ++i) index_->addPoint(data + i * std::size_t(dim), hnswlib::labeltype(i));
    index_->setEf(kEf);
    dim_ = dim;
  }
  void SearchOne(const float* q, int k, std::int64_t* ids, float* dists) override {
    auto top = index_->searchKnn(q, std::size_t(k));  // farthest first
    for (int i = k - 1; i >= 0; --i) {
      if (top.empty()) {
        ids[i] = -1;
        dists[i] = -1.f;
        continue;
      }
      // Results fill the last slots when fewer than k came back; shift them up.
      ids[i] = std::int64_t(top.top().second);
      dists[i] = top.top().first;
      top.pop();
    }
    int first = 0;
    while (first < k && ids[first] < 0) ++first;
    if (first > 0) {
      for (int i = 0; i + first < k; ++i) {
        ids[i] = ids[i + first];
        dists[i] = dists[i + first];
      }
      for (int i = k - first; i < k; ++i) ids[i] = -1, dists[i] = -1.f;
    }
  }
  // Level-0 block (links, vector, label) for every element plus the upper-level
  // link lists, the level array and the link-list pointers.
  double StructureBytes() const override {
    const auto& h = *index_;
    double bytes = double(h.max_elements_) * double(h.size_data_per_element_);
    for (std::size_t i = 0; i < h.cur_element_count; ++i) bytes += double(h.element_levels_[i]) * double(h.size_links_per_element_);
    bytes += double(h.max_elements_) * (sizeof(int) + sizeof(void*));
    return bytes;
  }

  // Untimed second pass over the queries with the distance function wrapped
  // (the timed pass runs hnswlib unchanged).
  double DistanceComputations(const float* queries, std::size_t nq, int k) override {
    g_inner_distance = index_->fstdistfunc_;
    g_distance_calls = 0;
    index_->fstdistfunc_ = &CountingDistance;
    for (std::size_t i = 0; i < nq; ++i) index_->searchKnn(queries + i * std::size_t(dim_), std::size_t(k));
    index_->fstdistfunc_ = g_inner_distance;
    return double(g_distance_calls);
  }

 private:
  std::unique_ptr<hnswlib::L2Space> space_;
  std::unique_ptr<hnswlib::HierarchicalNSW<float>> index_;
  int dim_ = 0;
};

}  // namespace

void AddHnswlibMethods(std::vector<MethodInfo>& out) {
  out.push_back({"hnswlib",
                 "HierarchicalNSW<float> L2 M=" + std::to_string(Hnswlib::kM) + " ef_construction=" +
                     std::to_string(Hnswlib::kEfConstruction) + " ef=" + std::to_string(Hnswlib::kEf),
                 "level-0 blocks + upper-level link lists + level/pointer arrays",
                 [] { return std::make_unique<Hnswlib>(); },
                 "calls of its distance function in a second, untimed pass over the queries"});
}

std::string HnswlibEnvironment() {
#if defined(USE_AVX512)
  return "hnswlib distance: AVX512/AVX compiled in (chosen at run time)";
#elif defined(USE_AVX)
  return "hnswlib distance: AVX compiled in (chosen at run time)";
#elif defined(USE_SSE)
  return "hnswlib distance: SSE (AVX not compiled in: no -mavx)";
#else
  return "hnswlib distance: scalar";
#endif
}

}  // namespace mvkp::bench
