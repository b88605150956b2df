// The nearest-neighbour methods mvkp_bench_knn compares, behind one interface.
//
// Every method indexes the same n x dim float database (row-major) and answers
// k-nearest-neighbour queries under squared L2. Baselines whose library was not
// found at configure time are simply absent from AllMethods().
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace mvkp::bench {

class Method {
 public:
  virtual ~Method() = default;

  // Copies or indexes n vectors; the caller's data may be freed afterwards.
  virtual void Build(const float* data, std::size_t n, int dim) = 0;

  // The k nearest vectors of one query, nearest first: ids[i] (-1 when not
  // found) and their squared distances as the library reports them.
  virtual void SearchOne(const float* query, int k, std::int64_t* ids, float* dists) = 0;

  // All nq queries in one library call (only when has_batch()); ids and dists
  // hold nq * k entries.
  virtual bool has_batch() const { return false; }
  virtual void SearchBatch(const float* queries, std::size_t nq, int k, std::int64_t* ids, float* dists) {}

  // Largest k the method answers (0: any). Further entries stay -1.
  virtual int max_k() const { return 0; }

  // Bytes the index holds according to its own data structures (sizes of its
  // arrays as the library exposes them), or < 0 when it does not expose them.
  virtual double StructureBytes() const { return -1; }

  // Exact distance computations (full query-to-vector distances; the cost
  // measure of thesis Fig. 5.3). ResetDistanceCount() runs before every timed
  // pass of single queries; DistanceComputations() after the last one returns
  // that pass's total over the nq queries, or < 0 when the method does not
  // report it. A method without a counter of its own may count by searching
  // the queries again (untimed).
  virtual void ResetDistanceCount() {}
  virtual double DistanceComputations(const float* queries, std::size_t nq, int k) { return -1; }
};

struct MethodInfo {
  std::string name;    // short, unique, no spaces: the row label
  std::string params;  // construction and search parameters, for the report
  std::string structure_how;  // how StructureBytes() counts, or "" if it does not
  std::function<std::unique_ptr<Method>()> make;
  std::string distances_how = "";  // how DistanceComputations() counts, or "" if it does not
};

// Every compiled-in method, in report order.
std::vector<MethodInfo> AllMethods();

// Per-library registration (methods_*.cc).
void AddMvkpMethods(std::vector<MethodInfo>& out);
void AddFaissMethods(std::vector<MethodInfo>& out);
void AddHnswlibMethods(std::vector<MethodInfo>& out);
void AddFlannMethods(std::vector<MethodInfo>& out);

// Environment notes for the report header ("" when not applicable): which BLAS
// FAISS calls, whether SIMD was compiled in, ...
std::string FaissEnvironment();
std::string HnswlibEnvironment();

// Pins every library's thread pool to one thread (OpenMP, OpenBLAS, OpenCV).
void SingleThreaded();

}  // namespace mvkp::bench
