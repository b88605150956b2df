#include "mvkp/rifs/rifs.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

// Three tracks in 2-D worked by hand (SPEC §4 formulas), L_SS = 2, N_V = 4.
TEST(Rifs, HandWorkedExample) {
  const float d[] = {0, 0, 2, 0,         // track 0: mean (1,0), VV = (1,0), VS = 0.5
                     10, 0, 10, 2, 10, 4,  // track 1: mean (10,2), VV = (0, 8/3), VS = 4/3
                     0, 10,               // track 2: SS 1 < L_SS: dropped
                     3, 4, 3, 4, 3, 4, 3, 4};  // track 3: mean (3,4), VS = 0 -> floor
  std::vector<std::vector<int>> tracks = {{0, 1}, {2, 3, 4}, {5}, {6, 7, 8, 9}};
  RifsOptions o;
  o.alpha = 0.5;
  o.min_stability = 2;
  o.num_views = 4;
  const auto s = ScoreTracks(d, 2, tracks, o);
  ASSERT_EQ(s.size(), 4u);
  EXPECT_FALSE(s[2].eligible);
  EXPECT_EQ(s[2].frs, 0);
  EXPECT_EQ(s[0].ss, 2);
  EXPECT_EQ(s[1].ss, 3);
  EXPECT_EQ(s[3].ss, 4);
  const double d01 = std::hypot(9.0, 2.0), d03 = std::hypot(2.0, 4.0), d13 = std::hypot(7.0, 2.0);
  EXPECT_NEAR(s[0].ds, (d01 + d03) / 3, 1e-6);
  EXPECT_NEAR(s[1].ds, (d01 + d13) / 3, 1e-6);
  EXPECT_NEAR(s[3].ds, (d03 + d13) / 3, 1e-6);
  EXPECT_NEAR(s[0].vs, 0.5, 1e-9);
  EXPECT_NEAR(s[1].vs, 4.0 / 3.0, 1e-6);
  EXPECT_NEAR(s[0].rrs, s[0].ds / 0.5, 1e-6);
  // Track 3 has the largest RRS (zero variance), track 1 the smallest.
  EXPECT_NEAR(s[3].rrs_scaled, 4.0, 1e-9);
  EXPECT_NEAR(s[1].rrs_scaled, 2.0, 1e-9);
  const double r0 = 2.0 + (s[0].rrs - s[1].rrs) * 2.0 / (s[3].rrs - s[1].rrs);
  EXPECT_NEAR(s[0].rrs_scaled, r0, 1e-9);
  EXPECT_NEAR(s[0].frs, 0.5 * r0 + 0.5 * 2, 1e-9);
  EXPECT_NEAR(s[1].frs, 0.5 * 2.0 + 0.5 * 3, 1e-9);
  const auto order = RankTracks(s);
  ASSERT_EQ(order.size(), 3u);
  EXPECT_EQ(order[0], 3);
}

TEST(Rifs, AlphaEndsRankByStabilityOrByRawScore) {
  std::mt19937 rng(5);
  std::normal_distribution<float> n(0.f, 1.f);
  const int dims = 6, nt = 40;
  std::vector<float> d;
  std::vector<std::vector<int>> tracks(nt);
  for (int j = 0; j < nt; ++j) {
    const int ss = 2 + j % 9;
    const float spread = 0.1f + 0.05f * ((j * 7) % 11);
    std::vector<float> c(dims);
    for (auto& v : c) v = 3.f * n(rng);
    for (int i = 0; i < ss; ++i) {
      tracks[j].push_back(int(d.size() / dims));
      for (int l = 0; l < dims; ++l) d.push_back(c[l] + spread * n(rng));
    }
  }
  RifsOptions o;
  o.min_stability = 3;
  o.num_views = 12;
  o.alpha = 0;
  auto s = ScoreTracks(d.data(), dims, tracks, o);
  auto order = RankTracks(s);
  for (std::size_t i = 1; i < order.size(); ++i) EXPECT_GE(s[order[i - 1]].ss, s[order[i]].ss);
  for (int j : order) EXPECT_GE(s[j].ss, 3);
  EXPECT_EQ(order.size(), std::size_t(std::count_if(tracks.begin(), tracks.end(), [](auto& t) { return t.size() >= 3; })));
  o.alpha = 1;
  s = ScoreTracks(d.data(), dims, tracks, o);
  order = RankTracks(s);
  for (std::size_t i = 1; i < order.size(); ++i) EXPECT_GE(s[order[i - 1]].rrs, s[order[i]].rrs);
  double lo = 1e9, hi = -1e9;
  for (int j : order) {
    lo = std::min(lo, s[j].rrs_scaled);
    hi = std::max(hi, s[j].rrs_scaled);
  }
  EXPECT_NEAR(lo, 3.0, 1e-9);
  EXPECT_NEAR(hi, 12.0, 1e-9);
}

TEST(Rifs, RepeatedElementsScoreLowerDistinctiveness) {
  // Five identical-looking tracks (repeated element) and five unique ones.
  std::vector<float> d;
  std::vector<std::vector<int>> tracks;
  for (int j = 0; j < 10; ++j) {
    std::vector<int> t;
    for (int i = 0; i < 5; ++i) {
      t.push_back(int(d.size() / 2));
      d.push_back(j < 5 ? 1.f + 0.01f * i : 10.f * j + 0.01f * i);
      d.push_back(j < 5 ? 1.f : -5.f * j);
    }
    tracks.push_back(t);
  }
  RifsOptions o;
  o.num_views = 5;
  const auto s = ScoreTracks(d.data(), 2, tracks, o);
  for (int a = 0; a < 5; ++a)
    for (int b = 5; b < 10; ++b) EXPECT_LT(s[a].ds, s[b].ds);
}

TEST(Rifs, BadOptionsThrow) {
  const float d[] = {0, 0};
  std::vector<std::vector<int>> t = {{0}};
  RifsOptions o;
  o.num_views = 10;
  o.alpha = 1.5;
  EXPECT_THROW(ScoreTracks(d, 2, t, o), Error);
  o.alpha = 0.5;
  o.min_stability = 20;
  EXPECT_THROW(ScoreTracks(d, 2, t, o), Error);
  o.min_stability = 1;
  EXPECT_NO_THROW(ScoreTracks(d, 2, t, o));
  EXPECT_TRUE(ScoreTracks(d, 2, {}, o).empty());
}

}  // namespace
}  // namespace mvkp
