#include "mvkp/index/knn_index.h"

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
