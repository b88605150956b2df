#include "mvkp/index/ivf.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// Clustered data as recognition has it: groups of nearby vectors sharing a
// label, scattered around a few hundred blob centres.
struct Data {
  int dim = 20;
  std::vector<float> x, centroids, queries;
  std::vector<std::int32_t> labels;
  std::size_t n() const { return labels.size(); }
};

Data MakeData(std::uint32_t seed, int blobs = 300, int per_label = 6, int labels_per_blob = 8, int ncent = 64,
              int nq = 400) {
  Data d;
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.f, 1.f);
  std::vector<float> blob(std::size_t(blobs) * d.dim);
  for (auto& v : blob) v = 4.f * g(rng);
  std::int32_t label = 0;
  for (int b = 0; b < blobs; ++b)
    for (int l = 0; l < labels_per_blob; ++l, ++label) {
      std::vector<float> c(d.dim);
      for (int j = 0; j < d.dim; ++j) c[j] = blob[std::size_t(b) * d.dim + j] + 0.8f * g(rng);
      for (int k = 0; k < per_label; ++k) {
        for (int j = 0; j < d.dim; ++j) d.x.push_back(c[j] + 0.2f * g(rng));
        d.labels.push_back(label);
      }
    }
  // Centroids: every k-th stored vector (a cheap stand-in for k-means).
  const std::size_t step = d.n() / std::size_t(ncent);
  for (int c = 0; c < ncent; ++c)
    d.centroids.insert(d.centroids.end(), d.x.begin() + std::ptrdiff_t(c * step * d.dim),
                       d.x.begin() + std::ptrdiff_t((c * step + 1) * d.dim));
  for (int q = 0; q < nq; ++q) {
    const std::size_t i = rng() % d.n();
    for (int j = 0; j < d.dim; ++j) d.queries.push_back(d.x[i * d.dim + j] + 0.3f * g(rng));
  }
  return d;
}

TEST(Ivf, AllListsProbedEqualsBruteForce) {
  const Data d = MakeData(1);
  const std::size_t C = d.centroids.size() / std::size_t(d.dim);
  IvfOptions o;
  o.nprobe = int(C);
  IvfIndex ivf(d.centroids.data(), C, d.dim, o);
  ivf.Build(d.x.data(), d.n(), d.dim, d.labels.data());
  auto brute = MakeBruteForceIndex();
  brute->Build(d.x.data(), d.n(), d.dim, d.labels.data());
  const std::size_t nq = d.queries.size() / std::size_t(d.dim);
  for (float ratio : {0.f, 0.8f}) {
    std::vector<Neighbor> a(2 * nq), b(2 * nq);
    ivf.SearchTwoDistinctBatch(d.queries.data(), nq, a.data(), ratio);
    brute->SearchTwoDistinctBatch(d.queries.data(), nq, b.data(), ratio);
    for (std::size_t i = 0; i < nq; ++i) {
      ASSERT_EQ(a[2 * i].id, b[2 * i].id) << i;
      ASSERT_EQ(a[2 * i].distance, b[2 * i].distance) << i;
      ASSERT_EQ(a[2 * i].label, b[2 * i].label) << i;
      // Outcome of the ratio test is exact; the second distance is exact
      // whenever it fails (KnnIndex's contract) and always without a ratio.
      const bool pass_a = std::sqrt(a[2 * i].distance) < ratio * std::sqrt(a[2 * i + 1].distance);
      const bool pass_b = std::sqrt(b[2 * i].distance) < ratio * std::sqrt(b[2 * i + 1].distance);
      ASSERT_EQ(pass_a, pass_b) << i;
      if (ratio == 0.f || !pass_a) {
        ASSERT_EQ(a[2 * i + 1].distance, b[2 * i + 1].distance) << i;
        ASSERT_EQ(a[2 * i + 1].label, b[2 * i + 1].label) << i;
      }
    }
  }
  for (std::size_t i = 0; i < 50; ++i) {
    Neighbor a[5], b[5];
    ivf.Search(d.queries.data() + i * d.dim, 5, a);
    brute->Search(d.queries.data() + i * d.dim, 5, b);
    for (int k = 0; k < 5; ++k) {
      EXPECT_EQ(a[k].id, b[k].id);
      EXPECT_EQ(a[k].distance, b[k].distance);
    }
  }
  EXPECT_EQ(ivf.size(), d.n());
  EXPECT_GT(ivf.memory_bytes(), d.n() * d.dim * sizeof(float));
}

TEST(Ivf, FewProbesFindMostNeighboursForAFractionOfTheWork) {
  const Data d = MakeData(2);
  const std::size_t C = d.centroids.size() / std::size_t(d.dim);
  IvfOptions o;
  o.nprobe = 6;
  IvfIndex ivf(d.centroids.data(), C, d.dim, o);
  ivf.Build(d.x.data(), d.n(), d.dim, d.labels.data());
  auto brute = MakeBruteForceIndex();
  brute->Build(d.x.data(), d.n(), d.dim, d.labels.data());
  const std::size_t nq = d.queries.size() / std::size_t(d.dim);
  std::vector<Neighbor> a(2 * nq), b(2 * nq);
  ivf.ResetStats();
  ivf.SearchTwoDistinctBatch(d.queries.data(), nq, a.data());
  brute->SearchTwoDistinctBatch(d.queries.data(), nq, b.data());
  int same = 0;
  for (std::size_t i = 0; i < nq; ++i) {
    same += a[2 * i].id == b[2 * i].id;
    // Never nearer than the truth: every reported neighbour exists.
    ASSERT_GE(a[2 * i].distance, b[2 * i].distance);
    ASSERT_GE(a[2 * i + 1].distance, b[2 * i + 1].distance);
  }
  EXPECT_GE(same, int(0.95 * double(nq)));
  EXPECT_LT(ivf.distance_computations(), nq * d.n() / 4);
}

TEST(Ivf, BuildAssignedMatchesBuildAndChecksInput) {
  const Data d = MakeData(3, 40, 4, 4, 16, 50);
  const std::size_t C = d.centroids.size() / std::size_t(d.dim);
  IvfIndex a(d.centroids.data(), C, d.dim), b(d.centroids.data(), C, d.dim);
  std::vector<std::int32_t> cells(d.n());
  a.Assign(d.x.data(), d.n(), cells.data());
  a.Build(d.x.data(), d.n(), d.dim, d.labels.data());
  b.BuildAssigned(d.x.data(), d.n(), d.dim, d.labels.data(), cells.data());
  const std::size_t nq = d.queries.size() / std::size_t(d.dim);
  std::vector<Neighbor> x(2 * nq), y(2 * nq);
  a.SearchTwoDistinctBatch(d.queries.data(), nq, x.data());
  b.SearchTwoDistinctBatch(d.queries.data(), nq, y.data());
  for (std::size_t i = 0; i < 2 * nq; ++i) EXPECT_EQ(x[i].id, y[i].id);

  cells[0] = std::int32_t(C);
  EXPECT_THROW(b.BuildAssigned(d.x.data(), d.n(), d.dim, d.labels.data(), cells.data()), Error);
  EXPECT_THROW(b.Build(d.x.data(), d.n(), d.dim + 1, d.labels.data()), Error);
  IvfOptions bad;
  bad.nprobe = 0;
  EXPECT_THROW(IvfIndex(d.centroids.data(), C, d.dim, bad), Error);
  std::vector<float> q(d.queries.begin(), d.queries.begin() + d.dim);
  q[3] = std::nanf("");
  Neighbor out[2];
  EXPECT_THROW(a.SearchTwoDistinct(q.data(), out), Error);
  // An empty index answers "nothing".
  IvfIndex e(d.centroids.data(), C, d.dim);
  e.Build(d.x.data(), 0, d.dim, d.labels.data());
  e.SearchTwoDistinct(d.queries.data(), out);
  EXPECT_EQ(out[0].id, -1);
  EXPECT_EQ(out[1].id, -1);
}

}  // namespace
}  // namespace mvkp
