// RIFS: rotation-invariant feature selection (thesis §3.3, SPEC §4).
//
// A view track T_j gathers the descriptors of one object location over the
// scoring views (general affine views plus rotation-dominant views). Each
// track is scored by
//   SS_j  stability: number of its descriptors (one per view at most);
//   M_j   mean descriptor;
//   DS_j  distinctiveness: (1/N_T) * sum_j' ||M_j - M_j'||;
//   VS_j  variance: (1/N_K) * sum_l VV_jl, VV_jl the per-dimension variance;
//   RRS_j = DS_j / VS_j, rescaled to the range of SS:
//   RRS'_j = L_SS + (RRS_j - min RRS) * (N_V - L_SS) / (max RRS - min RRS);
//   FRS_j = alpha * RRS'_j + (1 - alpha) * SS_j.
// Tracks with SS_j < L_SS are dropped before DS and the rescaling.
#pragma once

#include <cstddef>
#include <vector>

namespace mvkp {

struct RifsOptions {
  double alpha = 0.5;     // weight of the ranking score (0: stability only, 1: RRS only)
  int min_stability = 3;  // L_SS: tracks seen in fewer views are dropped
  int num_views = 0;      // N_V: number of scoring views (the largest possible SS)
  int min_samples = 2;    // tracks with fewer descriptors than this are not eligible (VS needs a spread)
  void Check() const;     // throws mvkp::Error(kInvalidArgument)
};

struct TrackScore {
  int ss = 0;          // stability
  double ds = 0;       // distinctiveness
  double vs = 0;       // variance
  double rrs = 0;      // raw rank score DS / VS
  double rrs_scaled = 0;  // RRS' in [L_SS, N_V]
  double frs = 0;      // final score
  bool eligible = false;  // SS >= L_SS (the other scores are 0 when false)
};

// Scores every track. `descriptors` holds rows of `dims` floats; tracks[j]
// lists the rows of track j that M_j, DS_j and VS_j are computed from. SS_j is
// stability[j] when given (e.g. counting views whose descriptors are not
// used for the statistics), else tracks[j].size(). Deterministic;
// O(N_T^2 * dims) for DS.
std::vector<TrackScore> ScoreTracks(const float* descriptors, int dims, const std::vector<std::vector<int>>& tracks,
                                    const RifsOptions& options, const std::vector<int>* stability = nullptr);

// Indices of eligible tracks ordered by FRS (highest first; ties by higher SS,
// then lower index).
std::vector<int> RankTracks(const std::vector<TrackScore>& scores);

}  // namespace mvkp
