#include "mvkp/index/knn_index.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp {
namespace {

TEST(L2Kernels, SimdEqualsScalarOnIntegerData) {
  if (!internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 rng(3);
  for (int dim = 1; dim <= 37; ++dim)
    for (std::size_t nb : {1u, 2u, 5u}) {
      std::vector<float> blocks(nb * dim * 8), q(dim), a(nb * 8), b(nb * 8);
      for (auto& v : blocks) v = float(int(rng() % 201) - 100);
      for (auto& v : q) v = float(int(rng() % 201) - 100);
      internal::L2Blocks8Scalar(blocks.data(), nb, q.data(), dim, a.data());
      internal::L2Blocks8Avx2(blocks.data(), nb, q.data(), dim, b.data());
      EXPECT_EQ(a, b) << "dim " << dim;
    }
}

TEST(L2Kernels, TwoDistinctSimdEqualsScalarOnIntegerData) {
  if (!internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 rng(5);
  for (int dim = 1; dim <= 37; ++dim)
    for (std::size_t nb : {1u, 3u, 40u}) {
      std::vector<float> blocks(nb * dim * 8), q(dim);
      std::vector<std::int32_t> labels(nb * 8);
      for (auto& v : blocks) v = float(int(rng() % 21) - 10);
      for (auto& v : q) v = float(int(rng() % 21) - 10);
      for (auto& l : labels) l = std::int32_t(rng() % 6) - 1;  // includes -1 padding lanes
      internal::TopTwo a = internal::EmptyTopTwo(), b = internal::EmptyTopTwo();
      internal::TwoDistinctScalar(blocks.data(), labels.data(), nb, q.data(), dim, 100, a);
      internal::TwoDistinctAvx2(blocks.data(), labels.data(), nb, q.data(), dim, 100, b);
      EXPECT_EQ(a.id1, b.id1) << dim;
      EXPECT_EQ(a.id2, b.id2) << dim;
      EXPECT_EQ(a.d1, b.d1);
      EXPECT_EQ(a.d2, b.d2);
    }
}

struct Data {
  int n, dim;
  std::vector<float> x;
  std::vector<std::int32_t> labels;
};

Data Random(int n, int dim, int nlabels, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g;
  Data d{n, dim, std::vector<float>(std::size_t(n) * dim), std::vector<std::int32_t>(n)};
  for (auto& v : d.x) v = g(rng);
  for (auto& l : d.labels) l = std::int32_t(rng() % nlabels);
  return d;
}

float D2(const float* a, const float* b, int dim) {
  float s = 0;
  for (int i = 0; i < dim; ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return s;
}

TEST(BruteForce, KnnAndTwoDistinctMatchANaiveScan) {
  for (int n : {1, 7, 8, 9, 300}) {
    const Data d = Random(n, 20, 5, n);
    const Data q = Random(25, 20, 1, 1000 + n);
    auto index = MakeBruteForceIndex();
    index->Build(d.x.data(), n, 20, d.labels.data());
    EXPECT_EQ(index->size(), std::size_t(n));
    for (int i = 0; i < q.n; ++i) {
      const float* qi = &q.x[i * 20];
      std::vector<std::pair<float, int>> all;
      for (int j = 0; j < n; ++j) all.push_back({D2(qi, &d.x[j * 20], 20), j});
      std::sort(all.begin(), all.end());
      Neighbor k3[3];
      index->Search(qi, 3, k3);
      for (int t = 0; t < 3; ++t) {
        if (t < n) {
          EXPECT_EQ(k3[t].id, all[t].second);
          EXPECT_NEAR(k3[t].distance, all[t].first, 1e-4f * (1 + all[t].first));
        } else {
          EXPECT_EQ(k3[t].id, -1);
        }
      }
      Neighbor two[2];
      index->SearchTwoDistinct(qi, two);
      EXPECT_EQ(two[0].id, all[0].second);
      int expect = -1;
      for (auto& [dist, j] : all)
        if (d.labels[j] != d.labels[all[0].second]) { expect = j; break; }
      EXPECT_EQ(two[1].id, expect);
      if (expect >= 0) {
        EXPECT_NE(two[1].label, two[0].label);
      }
    }
  }
}

TEST(BruteForce, RatioHintKeepsTheNearestAndTheTestOutcome) {
  const Data d = Random(500, 20, 40, 11), q = Random(200, 20, 1, 12);
  auto index = MakeBruteForceIndex();
  index->Build(d.x.data(), 500, 20, d.labels.data());
  for (float ratio : {0.6f, 0.8f, 0.95f})
    for (int i = 0; i < q.n; ++i) {
      Neighbor exact[2], hinted[2];
      index->SearchTwoDistinct(&q.x[i * 20], exact);
      index->SearchTwoDistinct(&q.x[i * 20], hinted, ratio);
      EXPECT_EQ(exact[0].id, hinted[0].id);
      const bool pass_exact = std::sqrt(exact[0].distance) < ratio * std::sqrt(exact[1].distance);
      const bool pass_hinted = std::sqrt(hinted[0].distance) < ratio * std::sqrt(hinted[1].distance);
      EXPECT_EQ(pass_exact, pass_hinted);
      EXPECT_GE(hinted[1].distance, exact[1].distance);
      if (!pass_exact) EXPECT_EQ(exact[1].id, hinted[1].id);
    }
}

TEST(BruteForce, BatchEqualsSingle) {
  const Data d = Random(100, 20, 10, 1), q = Random(17, 20, 1, 2);
  auto index = MakeBruteForceIndex();
  index->Build(d.x.data(), 100, 20, d.labels.data());
  std::vector<Neighbor> batch(2 * 17);
  index->SearchTwoDistinctBatch(q.x.data(), 17, batch.data());
  for (int i = 0; i < 17; ++i) {
    Neighbor one[2];
    index->SearchTwoDistinct(&q.x[i * 20], one);
    EXPECT_EQ(one[0].id, batch[2 * i].id);
    EXPECT_EQ(one[1].id, batch[2 * i + 1].id);
  }
}

}  // namespace
}  // namespace mvkp
