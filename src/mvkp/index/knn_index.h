// Nearest-neighbour search over labelled float vectors.
//
// Distances are squared Euclidean. Labels group vectors that describe the same
// thing (for MVKP: the k-means centres of one object location); the ratio test
// needs the nearest vector and the nearest one with a *different* label, since
// centres of one location are close to each other by design (SPEC §3).
// This interface knows nothing of images or keypoints.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

namespace mvkp {

struct Neighbor {
  std::int32_t id = -1;     // row of the vector in the data passed to Build
  std::int32_t label = -1;  // its label
  float distance = std::numeric_limits<float>::infinity();  // squared L2
};

class KnnIndex {
 public:
  virtual ~KnnIndex() = default;

  // Copies n vectors of `dim` floats (row-major) with one label each.
  virtual void Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) = 0;

  virtual std::size_t size() const = 0;
  virtual int dim() const = 0;
  virtual std::string name() const = 0;

  // The k nearest neighbours of one query, nearest first; out holds k entries,
  // unfilled ones (k > size) keep id -1 and infinite distance.
  virtual void Search(const float* query, int k, Neighbor* out) const = 0;

  // out[0]: the nearest vector; out[1]: the nearest vector whose label differs
  // from out[0].label (id -1 when every vector has that label).
  //
  // ratio > 0 serves a ratio test sqrt(d1) < ratio * sqrt(d2): the search may
  // then stop looking once no vector can change the test's outcome. out[0] and
  // the outcome stay exact; out[1] is exact whenever the test fails, and may
  // be farther than the true second neighbour (never nearer) when it passes.
  virtual void SearchTwoDistinct(const float* query, Neighbor out[2], float ratio = 0.f) const = 0;

  // Batched form: nq queries (row-major), out holds 2*nq entries.
  virtual void SearchTwoDistinctBatch(const float* queries, std::size_t nq, Neighbor* out, float ratio = 0.f) const {
    for (std::size_t i = 0; i < nq; ++i) SearchTwoDistinct(queries + i * std::size_t(dim()), out + 2 * i, ratio);
  }

  // Batched k-NN: nq queries (row-major), out holds k*nq entries.
  virtual void SearchBatch(const float* queries, std::size_t nq, int k, Neighbor* out) const {
    for (std::size_t i = 0; i < nq; ++i) Search(queries + i * std::size_t(dim()), k, out + i * std::size_t(k));
  }

  // Exact distance computations made by searches since the last ResetStats()
  // (all threads): the cost measure of thesis Fig. 5.3. Brute force makes n
  // per query; a filtering index makes as many as its filter lets through.
  virtual std::uint64_t distance_computations() const { return 0; }
  virtual void ResetStats() const {}

  // Bytes held by the index (its copy of the vectors included), for memory reports.
  virtual std::size_t memory_bytes() const = 0;
};

// Ties: every index orders neighbours by (distance, id), so equal distances
// resolve to the smaller id and exact indexes agree with brute force even on
// duplicated vectors. Queries with NaN or infinite values, and Build() with
// them, throw Error(kInvalidArgument).

// Exact linear scan, vectorised (AVX2 when the CPU has it, scalar otherwise).
std::unique_ptr<KnnIndex> MakeBruteForceIndex();

}  // namespace mvkp
