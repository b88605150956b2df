// FAISS baselines: exact IndexFlatL2 and graph-based IndexHNSWFlat.
#include <dlfcn.h>

#include <faiss/IndexFlat.h>
#include <faiss/IndexHNSW.h>
#include <faiss/impl/HNSW.h>
#include <faiss/utils/distances.h>

#include "methods.h"

namespace mvkp::bench {
namespace {

// Search plumbing shared by every FAISS index: one query, or nq in one call.
template <typename Index>
class FaissMethod : public Method {
 public:
  void SearchOne(const float* q, int k, std::int64_t* ids, float* dists) override {
    index_->search(1, q, k, dists, ids);
  }
  bool has_batch() const override { return true; }
  void SearchBatch(const float* q, std::size_t nq, int k, std::int64_t* ids, float* dists) override {
    index_->search(faiss::Index::idx_t(nq), q, k, dists, ids);
  }

 protected:
  std::unique_ptr<Index> index_;
};

class FaissFlat : public FaissMethod<faiss::IndexFlatL2> {
 public:
  void Build(const float* data, std::size_t n, int dim) override {
    index_ = std::make_unique<faiss::IndexFlatL2>(dim);
    index_->add(faiss::Index::idx_t(n), data);
  }
  double StructureBytes() const override { return double(index_->codes.size()); }
  // Exhaustive: every query is compared with every vector.
  double DistanceComputations(const float*, std::size_t nq, int) override {
    return double(nq) * double(index_->ntotal);
  }
};

class FaissHnsw : public FaissMethod<faiss::IndexHNSWFlat> {
 public:
  static constexpr int kM = 32, kEfSearch = 64;
  void Build(const float* data, std::size_t n, int dim) override {
    index_ = std::make_unique<faiss::IndexHNSWFlat>(dim, kM);
    index_->hnsw.efSearch = kEfSearch;
    index_->add(faiss::Index::idx_t(n), data);
  }
  double StructureBytes() const override {
    const auto& h = index_->hnsw;
    double bytes = double(h.neighbors.size()) * sizeof(h.neighbors[0]) + double(h.levels.size()) * sizeof(h.levels[0]) +
                   double(h.offsets.size()) * sizeof(h.offsets[0]);
    if (const auto* flat = dynamic_cast<const faiss::IndexFlatCodes*>(index_->storage)) bytes += double(flat->codes.size());
    return bytes;
  }
  // faiss::hnsw_stats (global, summed over searches): the distances of the
  // level-0 search (each newly visited vector once), not those of the greedy
  // descent through the upper levels. FAISS < 1.7.4 adds them to n3 (ndis only
  // on the unbounded-queue path), later versions to ndis.
  void ResetDistanceCount() override { faiss::hnsw_stats.reset(); }
  double DistanceComputations(const float*, std::size_t, int) override {
#if FAISS_VERSION_MAJOR == 1 && FAISS_VERSION_MINOR == 7 && FAISS_VERSION_PATCH < 4
    return double(faiss::hnsw_stats.n3) + double(faiss::hnsw_stats.ndis);
#else
    return double(faiss::hnsw_stats.ndis);
#endif
  }
};

}  // namespace

void AddFaissMethods(std::vector<MethodInfo>& out) {
  out.push_back({"faiss-flat", "IndexFlatL2 (exact)", "codes.size()", [] { return std::make_unique<FaissFlat>(); },
                 "n per query (exhaustive)"});
  out.push_back({"faiss-hnsw",
                 "IndexHNSWFlat M=" + std::to_string(FaissHnsw::kM) + " efConstruction=" +
                     std::to_string(faiss::HNSW(FaissHnsw::kM).efConstruction) +
                     " efSearch=" + std::to_string(FaissHnsw::kEfSearch),
                 "storage codes + hnsw neighbors, levels, offsets",
                 [] { return std::make_unique<FaissHnsw>(); }, "faiss::hnsw_stats (level-0 search only: n3 + ndis before FAISS 1.7.4, ndis after)"});
}

std::string FaissEnvironment() {
  std::string blas = "unknown";
  Dl_info info;
  if (void* sgemm = dlsym(RTLD_DEFAULT, "sgemm_"); sgemm && dladdr(sgemm, &info) && info.dli_fname)
    blas = info.dli_fname;
  return "FAISS " + std::to_string(FAISS_VERSION_MAJOR) + "." + std::to_string(FAISS_VERSION_MINOR) + "." +
         std::to_string(FAISS_VERSION_PATCH) + ", BLAS " + blas + " (batched flat search uses BLAS from " +
         std::to_string(faiss::distance_compute_blas_threshold) + " queries)";
}

}  // namespace mvkp::bench
