// An inverted-file index (IVF) over a fixed coarse quantiser: each stored
// vector sits in the list of its nearest coarse centroid, and a query scans
// only the lists of its `nprobe` nearest centroids.
//
// Approximate: a neighbour in a list that was not probed is missed, so unlike
// the FFVA and brute-force indexes this one is not exact unless nprobe equals
// the number of centroids (then it returns exactly what brute force returns).
// It trades that for speed on large sets where a query's neighbourhood is
// small against the whole: recognition among hundreds of targets (the
// recogniser's probe_words), whose k-means centres are quantised once with
// the visual vocabulary it already has.
//
// Lists are stored as brute force stores its data (blocks of 8 transposed,
// squared norms, AVX2 kernels with scalar references), and the queries that
// probe a list are scanned together, so each list is read once per batch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "mvkp/index/knn_index.h"

namespace mvkp {

struct IvfOptions {
  int nprobe = 8;  // lists scanned per query (1..number of centroids)
  void Check() const;
};

class IvfIndex final : public KnnIndex {
 public:
  // `centroids` holds ncentroids x dim floats (copied). Throws
  // Error(kInvalidArgument) for none, dim < 1 or non-finite values.
  IvfIndex(const float* centroids, std::size_t ncentroids, int dim, const IvfOptions& options = {});
  ~IvfIndex() override;

  // Assigns each vector to its nearest centroid, then stores it.
  void Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) override;
  // The same with the assignment given (cells[i] in 0..ncentroids-1), for
  // callers that keep it from an earlier build (a recogniser adding targets).
  void BuildAssigned(const float* data, std::size_t n, int dim, const std::int32_t* labels,
                     const std::int32_t* cells);
  // The nearest centroid of each of n vectors (what Build uses).
  void Assign(const float* data, std::size_t n, std::int32_t* cells) const;

  std::size_t size() const override { return n_; }
  int dim() const override { return dim_; }
  std::string name() const override { return "ivf"; }
  const IvfOptions& options() const { return options_; }

  // As KnnIndex, over the probed lists only. SearchTwoDistinct ignores
  // `ratio`: out[1] is always the nearest vector of another label in the
  // probed lists (exact there, whether or not a ratio test passes).
  void Search(const float* query, int k, Neighbor* out) const override;
  void SearchTwoDistinct(const float* query, Neighbor out[2], float ratio = 0.f) const override;
  void SearchTwoDistinctBatch(const float* queries, std::size_t nq, Neighbor* out, float ratio = 0.f) const override;

  std::uint64_t distance_computations() const override;
  void ResetStats() const override;
  std::size_t memory_bytes() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  IvfOptions options_;
  std::size_t n_ = 0;
  int dim_ = 0;
};

}  // namespace mvkp
