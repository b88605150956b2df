// Augmented features (thesis chapter 4, SPEC §7): ordinal codes of
// "relative features" of sub-images, matched with rank-correlation metrics.
//
// For keypoint P_i with base descriptor D(P_i) (any descriptor with `dim`
// components: SIFT, CDIKP, ...):
//   S(P_i)    the sub-image: P_i (the leader) and its k nearest keypoints in
//             IMAGE space (the members), Euclidean distance of KeyPoint::pt,
//             equal distances broken by the smaller keypoint index.
//   R_j(P_i)  = sum over members n of |D_j(P_n) - D_j(P_i)|, j = 1..dim
//             (thesis §4.1.2, the "relative feature").
//   A_j(P_i)  = |{m : R_m(P_i) <= R_j(P_i)}| with ties broken (thesis §4.1.3):
//             the rank of R_j among R's components, 1 = smallest, so every
//             code is a permutation of 1..dim.
//
// Ties R_j == R_j' (frequent with integer-valued descriptors such as
// OpenCV's SIFT: dimensions that are 0 in the whole sub-image) are broken by
// TieMode:
//   kLocal  (thesis Table 4.1, "(L)"): the next nearest keypoints are added to
//           the sub-image one at a time, up to max_tie_iterations of them, and
//           R recomputed after each; tied dimensions are ordered by the first
//           recomputed R in which they differ (lexicographic over the
//           iterations, which is the thesis's pairwise rule extended to groups
//           of more than two), and by dimension index when they never differ.
//   kGlobal ("(G)"): tied dimensions are ordered by a global reference
//           vector, the mean descriptor of all keypoints of the image
//           (smaller mean first), then by index.
//
// Invariance: codes depend only on which keypoints are neighbours (so they do
// not change under rotation / translation / uniform scaling of the keypoint
// set, unless that reorders nearly equal distances) and on the order of the R
// components (so not under scaling of all descriptors by a positive constant).
//
// Metrics between codes A, A' (thesis §4.2; D = dim):
//   kSpearman  similarity 1 - 3 sum_j (A_j - A'_j)^2 / (D (D^2 - 1)), in [0, 1]
//              for permutations (1 identical, 0 reversed; = (1 + rho) / 2 with
//              rho the usual Spearman coefficient). Dissimilarity: the
//              Euclidean distance between the rank vectors,
//              sqrt(sum_j (A_j - A'_j)^2), monotone in 1 - similarity and on
//              the scale of an L2 ratio test. The default.
//   kKendall   similarity tau = 2 sum_{j<m} sign(A_j - A_m) sign(A'_j - A'_m)
//              / (D (D - 1)), in [-1, 1]. Dissimilarity (1 - tau) / 2, the
//              fraction of discordant pairs. O(D^2) per pair (see
//              KnnMatchCodes for the faster path on permutations).
//   kCount     the thesis's |{j : A_j != A'_j}| is a distance; it is the
//              dissimilarity here. Similarity: the fraction of agreeing
//              positions, 1 - |{j : A_j != A'_j}| / D, in [0, 1].
// With dim 1 the Spearman and Kendall normalisations divide by 0; both
// similarities are then defined as 1 (and the dissimilarities as 0).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

enum class AugmentMetric { kSpearman, kKendall, kCount };
enum class TieMode { kLocal, kGlobal };

struct AugmentOptions {
  int k = 5;  // members of a sub-image besides its leader (thesis: k = 5)
  TieMode ties = TieMode::kLocal;  // how ties in R are broken (thesis Table 4.1 "(L)" / "(G)")
  // Local tie breaking: most extra neighbours added one at a time (thesis: M,
  // value not given). 5 at most doubles the sub-image at the default k. With
  // OpenCV SIFT (integer-valued) every keypoint of starry_night at 800 px has
  // tied R components; after 5 extra neighbours about 0.09 tied groups per
  // keypoint are left, ordered by index.
  int max_tie_iterations = 5;
  void Check() const;  // throws mvkp::Error(kInvalidArgument)
};

// Ordinal codes, one row per keypoint: N x dim, CV_8U when dim <= 255 (values
// 1..dim), else CV_16U. `descriptors` has one row per keypoint (N rows, dim
// columns, one channel) and is CV_32F or CV_8U; CV_8U bytes are treated as
// numbers, which suits byte-quantised real-valued descriptors but makes little
// sense for binary ones (ORB, BRIEF, AKAZE's MLDB), where a byte packs 8 bits.
// Other types (CV_64F included: convert it yourself) throw
// Error(kInvalidArgument, "mismatched descriptor type ..."), as do differing
// counts, non-finite keypoint coordinates and dim > 65535. With fewer than
// k + 1 keypoints every sub-image uses all the others; a single keypoint gets
// the code ordered by tie breaking alone. No keypoints: an empty Mat.
// NaN descriptor values give unspecified (but valid permutation) codes.
cv::Mat Augment(const std::vector<cv::KeyPoint>& keypoints, const cv::Mat& descriptors,
                const AugmentOptions& options = {});

// Similarity / dissimilarity of two codes of `dim` values (see the table
// above). Any values are accepted; for Kendall, equal values in a code count
// sign 0 as in the formula.
double Similarity(const std::uint8_t* a, const std::uint8_t* b, int dim, AugmentMetric metric);
double Similarity(const std::uint16_t* a, const std::uint16_t* b, int dim, AugmentMetric metric);
double Dissimilarity(const std::uint8_t* a, const std::uint8_t* b, int dim, AugmentMetric metric);
double Dissimilarity(const std::uint16_t* a, const std::uint16_t* b, int dim, AugmentMetric metric);
// The same on two single rows (1 x dim, both CV_8U or both CV_16U).
double Similarity(const cv::Mat& a, const cv::Mat& b, AugmentMetric metric);
double Dissimilarity(const cv::Mat& a, const cv::Mat& b, AugmentMetric metric);

// The two rows of codes2 nearest to one row of codes1 by Dissimilarity; equal
// dissimilarities go to the smaller row index. second = -1 and d2 = +inf when
// codes2 has one row; best = -1, d1 = d2 = +inf when it has none.
struct TwoNearest {
  int best = -1, second = -1;
  double d1 = 0, d2 = 0;
};

// Exhaustive 2-NN of every row of codes1 among the rows of codes2 (both
// CV_8U or both CV_16U, same number of columns). One thread. For CV_8U codes
// Spearman and count use integer kernels (AVX2 when available): at dim 128
// about 3.3 and 5.6 ns per pair, i.e. 30 / 50 ms for 3000 x 3000. Kendall
// counts discordant pairs as popcount(xor) of dim(dim-1)/2-bit sets when no
// row of either set repeats a value (as Augment's codes): about 50 ns per
// pair at dim 128; otherwise, and for CV_16U codes, the O(dim^2) formula per
// pair, which is much slower. Note that the count metric's integer distances
// bunch near dim for permutations, so its ratio test rarely passes.
std::vector<TwoNearest> KnnMatchCodes(const cv::Mat& codes1, const cv::Mat& codes2, AugmentMetric metric);

// Ratio test on KnnMatchCodes: keeps row i of codes1 when d1 < ratio * d2
// (always when there is no second row). ratio in (0, 1]. queryIdx = row of
// codes1, trainIdx = row of codes2, distance = d1.
std::vector<cv::DMatch> MatchCodes(const cv::Mat& codes1, const cv::Mat& codes2, AugmentMetric metric,
                                   double ratio);

}  // namespace mvkp
