#include "mvkp/rifs/rifs.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "mvkp/core/error.h"

namespace mvkp {

void RifsOptions::Check() const {
  Require(alpha >= 0.0 && alpha <= 1.0, ErrorCode::kInvalidArgument,
          "alpha must be in [0, 1], got " + std::to_string(alpha));
  Require(min_stability >= 1, ErrorCode::kInvalidArgument,
          "min stability must be >= 1, got " + std::to_string(min_stability));
  Require(min_samples >= 1, ErrorCode::kInvalidArgument, "min samples must be >= 1");
  Require(num_views >= min_stability, ErrorCode::kInvalidArgument,
          "number of scoring views (" + std::to_string(num_views) + ") must be >= min stability (" +
              std::to_string(min_stability) + ")");
}

std::vector<TrackScore> ScoreTracks(const float* desc, int dims, const std::vector<std::vector<int>>& tracks,
                                    const RifsOptions& opt, const std::vector<int>* stability) {
  opt.Check();
  Require(!stability || stability->size() == tracks.size(), ErrorCode::kInvalidArgument,
          "one stability count per track expected");
  Require(dims >= 1, ErrorCode::kInvalidArgument, "descriptor dimension must be >= 1");
  const int nt = int(tracks.size());
  std::vector<TrackScore> s(nt);
  std::vector<int> elig;
  for (int j = 0; j < nt; ++j) {
    s[j].ss = stability ? (*stability)[j] : int(tracks[j].size());
    s[j].eligible = s[j].ss >= opt.min_stability && int(tracks[j].size()) >= opt.min_samples;
    if (s[j].eligible) elig.push_back(j);
  }
  const int ne = int(elig.size());
  if (ne == 0) return s;

  // Means M_j and variances VS_j (double accumulation).
  std::vector<float> mean(std::size_t(ne) * dims);
  std::vector<double> m(dims);
  for (int e = 0; e < ne; ++e) {
    const auto& t = tracks[elig[e]];
    std::fill(m.begin(), m.end(), 0.0);
    for (int i : t)
      for (int l = 0; l < dims; ++l) m[l] += desc[std::size_t(i) * dims + l];
    for (int l = 0; l < dims; ++l) m[l] /= double(t.size());
    double vv = 0;
    for (int i : t)
      for (int l = 0; l < dims; ++l) {
        const double d = desc[std::size_t(i) * dims + l] - m[l];
        vv += d * d;
      }
    s[elig[e]].vs = vv / double(t.size()) / dims;
    for (int l = 0; l < dims; ++l) mean[std::size_t(e) * dims + l] = float(m[l]);
  }

  // DS_j = (1/N_T) sum_j' ||M_j - M_j'|| over the eligible tracks (j' = j adds 0).
  std::vector<double> ds(ne, 0.0);
  for (int a = 0; a < ne; ++a) {
    const float* ma = &mean[std::size_t(a) * dims];
    double acc = 0;
    for (int b = a + 1; b < ne; ++b) {
      const float* mb = &mean[std::size_t(b) * dims];
      float d2 = 0;
      for (int l = 0; l < dims; ++l) {
        const float d = ma[l] - mb[l];
        d2 += d * d;
      }
      const double d = std::sqrt(double(d2));
      acc += d;
      ds[b] += d;
    }
    ds[a] += acc;
  }

  double lo = INFINITY, hi = -INFINITY;
  for (int e = 0; e < ne; ++e) {
    TrackScore& t = s[elig[e]];
    t.ds = ds[e] / ne;
    t.rrs = t.ds / std::max(t.vs, 1e-12);
    lo = std::min(lo, t.rrs);
    hi = std::max(hi, t.rrs);
  }
  const double l_ss = opt.min_stability, n_v = opt.num_views;
  for (int e = 0; e < ne; ++e) {
    TrackScore& t = s[elig[e]];
    // All equal: every track gets the middle of the range, so FRS orders by SS.
    t.rrs_scaled = hi > lo ? l_ss + (t.rrs - lo) * (n_v - l_ss) / (hi - lo) : 0.5 * (l_ss + n_v);
    t.frs = opt.alpha * t.rrs_scaled + (1.0 - opt.alpha) * t.ss;
  }
  return s;
}

std::vector<int> RankTracks(const std::vector<TrackScore>& s) {
  std::vector<int> order;
  for (int j = 0; j < int(s.size()); ++j)
    if (s[j].eligible) order.push_back(j);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (s[a].frs != s[b].frs) return s[a].frs > s[b].frs;
    return s[a].ss > s[b].ss;
  });
  return order;
}

}  // namespace mvkp
