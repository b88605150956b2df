#include "mvkp/wht/wht.h"

#include <algorithm>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

namespace mvkp::wht {
namespace {

std::vector<std::uint8_t> RandomPatch(int k, std::uint64_t seed, bool smooth) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint8_t> p(std::size_t(k) * k);
  if (!smooth) {
    for (auto& v : p) v = std::uint8_t(rng() % 256);
    return p;
  }
  // A natural-image-like patch: a few low-frequency blobs plus mild noise.
  std::uniform_real_distribution<double> u(0, 1);
  double a[4][4];
  for (auto& r : a) for (double& v : r) v = u(rng);
  for (int y = 0; y < k; ++y)
    for (int x = 0; x < k; ++x) {
      double v = 0;
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) v += a[i][j] * std::cos(3.14159 * i * y / k) * std::cos(3.14159 * j * x / k);
      p[std::size_t(y) * k + x] = std::uint8_t(std::clamp(60 + 40 * v + 4 * (u(rng) - 0.5), 0.0, 255.0));
    }
  return p;
}

TEST(Walsh1D, RowsHaveSequencySignChangesAndAreOrthogonal) {
  for (int n : {1, 2, 4, 8, 32, 64}) {
    const auto w = Walsh1D(n);
    ASSERT_EQ(int(w.size()), n);
    for (int s = 0; s < n; ++s) {
      int changes = 0;
      for (int x = 1; x < n; ++x) changes += w[s][x] != w[s][x - 1];
      EXPECT_EQ(changes, s);
      for (int t = 0; t < n; ++t) {
        int dot = 0;
        for (int x = 0; x < n; ++x) dot += w[s][x] * w[t][x];
        EXPECT_EQ(dot, s == t ? n : 0);
      }
    }
  }
}

TEST(Walsh1D, LowSequencyKernelsAreUpsampledShortKernels) {
  // The identity the fast projection rests on.
  const auto w32 = Walsh1D(32), w8 = Walsh1D(8);
  for (int s = 0; s < 8; ++s)
    for (int x = 0; x < 32; ++x) EXPECT_EQ(w32[s][x], w8[s][x / 4]);
}

TEST(ZigZag, OrdersByDiagonalAndAlternates) {
  const auto z = ZigZagOrder(32, 21);
  ASSERT_EQ(z.size(), 21u);
  EXPECT_EQ(z[0].u + z[0].v, 0);
  for (std::size_t i = 1; i < z.size(); ++i) EXPECT_LE(z[i - 1].u + z[i - 1].v, z[i].u + z[i].v);
  EXPECT_EQ(z[1].u, 0); EXPECT_EQ(z[1].v, 1);  // diagonal 1 goes (0,1), (1,0)
  EXPECT_EQ(z[3].u, 2); EXPECT_EQ(z[3].v, 0);  // diagonal 2 comes back from (2,0)
  // All distinct.
  for (std::size_t i = 0; i < z.size(); ++i)
    for (std::size_t j = i + 1; j < z.size(); ++j) EXPECT_FALSE(z[i].u == z[j].u && z[i].v == z[j].v);
}

TEST(Projector, FastProjectionEqualsDirectSum) {
  for (int dims : {1, 8, 20, 35, 100}) {
    Projector proj({32, dims, true});
    const auto patch = RandomPatch(32, 7 + dims, false);
    std::vector<std::int32_t> out(proj.dims());
    proj.Project(patch.data(), 32, out.data());
    for (int i = 0; i < proj.dims(); ++i)
      EXPECT_EQ(out[i], ProjectDirect(patch.data(), 32, 32, proj.kernels()[i])) << "dims " << dims << " kernel " << i;
  }
  Projector p20({32, 20, true});
  EXPECT_EQ(p20.grid(), 8);  // K = 20 only needs 8x8 block sums
}

TEST(Projector, ProjectGridMatchesProject) {
  Projector proj({32, 20, true});
  const auto patch = RandomPatch(32, 3, false);
  const int n = proj.grid(), b = proj.block();
  std::vector<float> grid(n * n, 0.f);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) grid[(y / b) * n + x / b] += patch[y * 32 + x];
  std::vector<std::int32_t> exact(proj.dims());
  std::vector<float> fast(proj.dims());
  proj.Project(patch.data(), 32, exact.data());
  proj.ProjectGrid(grid.data(), fast.data());
  for (int i = 0; i < proj.dims(); ++i) EXPECT_FLOAT_EQ(fast[i], float(exact[i]));
}

double FullDist2(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += double(int(a[i]) - int(b[i])) * (int(a[i]) - int(b[i]));
  return s;
}

TEST(Projector, PrefixDistancesLowerBoundTheFullDistanceAndTighten) {
  const int k = 32;
  Projector proj({k, 1024, false});  // every kernel, DC included
  for (int trial = 0; trial < 10; ++trial) {
    const auto a = RandomPatch(k, 100 + trial, trial % 2 == 0), b = RandomPatch(k, 200 + trial, trial % 2 == 0);
    std::vector<std::int32_t> ca(proj.dims()), cb(proj.dims());
    proj.Project(a.data(), k, ca.data());
    proj.Project(b.data(), k, cb.data());
    const double full = FullDist2(a, b);
    double prefix = 0, prev = 0;
    for (int i = 0; i < proj.dims(); ++i) {
      const double d = double(ca[i]) - cb[i];
      prefix += d * d / (k * k);
      EXPECT_LE(prefix, full * (1 + 1e-12) + 1e-9);
      EXPECT_GE(prefix, prev);
      prev = prefix;
    }
    EXPECT_NEAR(prefix, full, full * 1e-9);  // all k*k kernels: Parseval
  }
}

TEST(Projector, ConvergesFasterThanTheStandardBasis) {
  // Thesis Fig. 3.7: on image-like patches the first 20-50 WH kernels capture
  // most of the distance; the first 20-50 pixels (standard basis) do not.
  const int k = 32;
  Projector proj({k, 50, false});
  double wh20 = 0, wh50 = 0, std20 = 0, std50 = 0, full = 0;
  for (int trial = 0; trial < 20; ++trial) {
    const auto a = RandomPatch(k, 300 + trial, true), b = RandomPatch(k, 400 + trial, true);
    std::vector<std::int32_t> ca(proj.dims()), cb(proj.dims());
    proj.Project(a.data(), k, ca.data());
    proj.Project(b.data(), k, cb.data());
    for (int i = 0; i < 50; ++i) {
      const double dw = (double(ca[i]) - cb[i]) * (double(ca[i]) - cb[i]) / (k * k);
      const double ds = double(int(a[i]) - int(b[i])) * (int(a[i]) - int(b[i]));
      if (i < 20) { wh20 += dw; std20 += ds; }
      wh50 += dw;
      std50 += ds;
    }
    full += FullDist2(a, b);
  }
  EXPECT_GT(wh20 / full, 0.7);
  EXPECT_GT(wh50 / full, 0.85);
  EXPECT_LT(std20 / full, 0.1);
  EXPECT_GT(wh20, 5 * std20);
  EXPECT_GT(wh50, 5 * std50);
}

TEST(Projector, RejectsBadOptions) {
  EXPECT_THROW(Projector({30, 20, true}), std::exception);
  EXPECT_THROW(Projector({32, 0, true}), std::exception);
  EXPECT_THROW(Projector({32, 1024, true}), std::exception);
}

}  // namespace
}  // namespace mvkp::wht
