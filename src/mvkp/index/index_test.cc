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
    for (std::size_t nb : {1u, 2u, 4u, 5u, 9u, 11u}) {  // the four-block loop, its tail, both
      std::vector<float> blocks(nb * dim * 8), q(dim), a(nb * 8), b(nb * 8);
      for (auto& v : blocks) v = float(int(rng() % 201) - 100);
      for (auto& v : q) v = float(int(rng() % 201) - 100);
      internal::L2Blocks8Scalar(blocks.data(), nb, q.data(), dim, a.data());
      internal::L2Blocks8Avx2(blocks.data(), nb, q.data(), dim, b.data());
      EXPECT_EQ(a, b) << "dim " << dim;
    }
}

// Each lane sums its dimensions in the same order with fused multiply-adds
// in both kernels, so even real-valued distances agree to the bit (the
// search's answers must not depend on which kernel the CPU gets).
TEST(L2Kernels, SimdEqualsScalarBitForBitOnRealData) {
  if (!internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 rng(11);
  std::normal_distribution<float> g(0.f, 3.f);
  for (int dim : {1, 7, 20, 33})
    for (std::size_t nb : {3u, 4u, 8u, 13u}) {
      std::vector<float> blocks(nb * dim * 8), q(dim), a(nb * 8), b(nb * 8);
      for (auto& v : blocks) v = g(rng);
      for (auto& v : q) v = g(rng);
      internal::L2Blocks8Scalar(blocks.data(), nb, q.data(), dim, a.data());
      internal::L2Blocks8Avx2(blocks.data(), nb, q.data(), dim, b.data());
      for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], b[i]) << "dim " << dim << " nb " << nb << " lane " << i;
    }
}

TEST(L2Kernels, TwoDistinctNormSimdEqualsScalarOnIntegerData) {
  if (!internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 rng(5);
  for (int dim = 1; dim <= 37; ++dim)
    for (std::size_t nb : {1u, 3u, 40u})
      for (int nq = 1; nq <= 4; ++nq)
        for (float ratio : {0.f, 0.8f}) {
          std::vector<float> blocks(nb * dim * 8), q(std::size_t(nq) * dim), norms(nb * 8), qn(nq);
          std::vector<std::int32_t> labels(nb * 8);
          for (auto& v : blocks) v = float(int(rng() % 21) - 10);
          for (auto& v : q) v = float(int(rng() % 21) - 10);
          for (auto& l : labels) l = std::int32_t(rng() % 6) - 1;  // includes -1 padding lanes
          for (std::size_t i = 0; i < nb * 8; ++i) {
            std::vector<float> x(dim);
            for (int d = 0; d < dim; ++d) x[d] = blocks[(i / 8 * dim + d) * 8 + i % 8];
            norms[i] = internal::SquaredNorm(x.data(), dim);
          }
          for (int k = 0; k < nq; ++k) qn[k] = internal::SquaredNorm(&q[k * dim], dim);
          internal::TopTwo a[4], b[4];
          for (int k = 0; k < 4; ++k) a[k] = b[k] = internal::EmptyTopTwo(ratio);
          internal::TwoDistinctNormScalar(blocks.data(), norms.data(), labels.data(), nb, q.data(), qn.data(), nq, dim, a);
          internal::TwoDistinctNormAvx2(blocks.data(), norms.data(), labels.data(), nb, q.data(), qn.data(), nq, dim, b);
          for (int k = 0; k < nq; ++k) {
            EXPECT_EQ(a[k].id1, b[k].id1) << dim << " " << nq;
            EXPECT_EQ(a[k].id2, b[k].id2) << dim << " " << nq;
            EXPECT_EQ(a[k].d1, b[k].d1);
            EXPECT_EQ(a[k].d2, b[k].d2);
          }
        }
}

TEST(L2Kernels, NearestRowsSimdEqualsScalarAndTheBruteForceIndex) {
  // Integer data with few values: ties everywhere, at the k-th place too.
  // Real-valued data: the distances must agree bit for bit to agree on rows.
  if (!internal::CpuHasAvx2()) GTEST_SKIP() << "no AVX2";
  std::mt19937 rng(5);
  for (int integer : {1, 0})
    for (int n : {1, 3, 4, 7, 87, 130})
      for (int dim : {1, 6, 20})
        for (int k : {1, 2, 5, 8}) {
          const std::size_t nq = 1 + rng() % 21;
          std::vector<float> x(std::size_t(n) * dim), q(nq * dim);
          std::normal_distribution<float> g;
          for (auto& v : x) v = integer ? float(int(rng() % 3) - 1) : g(rng);
          for (auto& v : q) v = integer ? float(int(rng() % 3) - 1) : g(rng);
          std::vector<std::int32_t> a(nq * k), b(nq * k);
          internal::NearestRowsScalar(x.data(), n, dim, q.data(), nq, k, a.data());
          internal::NearestRowsAvx2(x.data(), n, dim, q.data(), nq, k, b.data());
          ASSERT_EQ(a, b) << "n " << n << " dim " << dim << " k " << k;
          auto index = MakeBruteForceIndex();
          index->Build(x.data(), n, dim, nullptr);
          std::vector<Neighbor> c(nq * k);
          index->SearchBatch(q.data(), nq, k, c.data());
          for (std::size_t i = 0; i < c.size(); ++i) ASSERT_EQ(c[i].id, a[i]) << i;
        }
}

TEST(BruteForce, TwoDistinctEqualsANaiveScanOnIntegerData) {
  // Integer data: the norm expansion is exact, so ids must match a plain scan.
  std::mt19937 rng(9);
  for (int n : {1, 5, 8, 17, 1000}) {
    const int dim = 20;
    std::vector<float> x(std::size_t(n) * dim), q(13 * dim);
    std::vector<std::int32_t> labels(n);
    for (auto& v : x) v = float(int(rng() % 31) - 15);
    for (auto& v : q) v = float(int(rng() % 31) - 15);
    for (auto& l : labels) l = std::int32_t(rng() % 7);
    auto index = MakeBruteForceIndex();
    index->Build(x.data(), n, dim, labels.data());
    std::vector<Neighbor> batch(2 * 13);
    index->SearchTwoDistinctBatch(q.data(), 13, batch.data());
    for (int i = 0; i < 13; ++i) {
      float d1 = INFINITY, d2 = INFINITY;
      int i1 = -1, i2 = -1;
      for (int j = 0; j < n; ++j) {
        float d = 0;
        for (int t = 0; t < dim; ++t) d += (x[j * dim + t] - q[i * dim + t]) * (x[j * dim + t] - q[i * dim + t]);
        if (d < d1) {
          if (i1 < 0 || labels[j] != labels[i1]) { d2 = d1; i2 = i1; }
          d1 = d; i1 = j;
        } else if (d < d2 && labels[j] != labels[i1]) {
          d2 = d; i2 = j;
        }
      }
      EXPECT_EQ(batch[2 * i].id, i1);
      EXPECT_EQ(batch[2 * i + 1].id, i2);
      EXPECT_EQ(batch[2 * i].distance, d1);
    }
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

TEST(BruteForce, KnnOnIntegerDataBreaksTiesByRowLikeAStableSort) {
  // Few distinct values: many exact ties, at the k-th place too. The k
  // nearest must be those of a stable sort by distance (the first stored
  // wins a tie), for k below, at and above the number of chunks the
  // selection bounds with, and above n.
  std::mt19937 rng(21);
  for (int n : {1, 2, 9, 16, 17, 87, 88, 250})
    for (int k : {1, 2, 3, 8, 16, 40, 300}) {
      const int dim = 6;
      std::vector<float> x(std::size_t(n) * dim), q(9 * dim);
      for (auto& v : x) v = float(int(rng() % 3) - 1);
      for (auto& v : q) v = float(int(rng() % 3) - 1);
      auto index = MakeBruteForceIndex();
      index->Build(x.data(), n, dim, nullptr);
      std::vector<Neighbor> batch(std::size_t(9) * k);
      index->SearchBatch(q.data(), 9, k, batch.data());
      for (int i = 0; i < 9; ++i) {
        std::vector<std::pair<float, int>> all;
        for (int j = 0; j < n; ++j) all.push_back({D2(&q[i * dim], &x[j * dim], dim), j});
        std::stable_sort(all.begin(), all.end(), [](auto& a, auto& b) { return a.first < b.first; });
        std::vector<Neighbor> one(k);
        index->Search(&q[i * dim], k, one.data());
        for (int t = 0; t < k; ++t) {
          const Neighbor& b = batch[std::size_t(i) * k + t];
          EXPECT_EQ(b.id, one[t].id);
          if (t < n) {
            ASSERT_EQ(b.id, all[t].second) << "n " << n << " k " << k << " rank " << t;
            EXPECT_EQ(b.distance, all[t].first);
          } else {
            EXPECT_EQ(b.id, -1);
          }
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
      if (!pass_exact) {
        EXPECT_EQ(exact[1].id, hinted[1].id);
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
