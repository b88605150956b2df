// Multi-target recognition (thesis ch. 6, SPEC §8): which of many trained
// targets are in a frame, if any.
//
// One search index holds the k-means centres of ALL targets, each labelled
// with a global location id (the target's location offset + its location).
// Per frame the query features are extracted once, with the feature settings
// every target shares; each descriptor gets its nearest centre and the nearest
// centre of a DIFFERENT location (possibly of another target, so a point that
// looks like two targets is dropped by the ratio test); the surviving matches
// vote for their target. Up to max_candidates targets with at least min_votes
// votes (most votes first) are verified by a robust homography over their own
// correspondences, as Matcher does (same estimator, plausible-outline check,
// fixed RNG state, so results are deterministic); those with >= min_inliers
// inliers are reported, most inliers first. Several targets can be found in
// one frame; "no target" is an empty `found`.
//
// Not yet done (Matcher has them, the recogniser ignores the options):
// the half-resolution retry (MatchOptions::half_res_points /
// retry_below_inliers), the dynamic ratio (dynamic_goal, ratio_min/max) and
// per-target dynamic thresholds, temporal tracking over video, and the
// two-stage shortlist that SPEC §8 needs for ~1000 targets.
// MatchOptions::min_inliers is replaced by RecognizerOptions::min_inliers.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/index/knn_index.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"

namespace mvkp {

struct RecognizerOptions {
  MatchOptions match;      // query points, ratio, geometry, robust estimator, RANSAC threshold, index kind
  int max_candidates = 5;  // targets verified per frame, most votes first
  int min_votes = 8;       // ratio-test matches a target needs to be verified
  int min_inliers = 12;    // RANSAC inliers to accept a target
  void Check() const;
};

struct Recognition {
  std::string id;
  cv::Matx33d homography = cv::Matx33d::eye();  // object pixels -> frame pixels
  std::array<cv::Point2f, 4> outline{};         // object corners (0,0),(w-1,0),(w-1,h-1),(0,h-1) in the frame
  int inliers = 0;                              // RANSAC inliers
  int votes = 0;                                // ratio-test matches that pointed to this target
  double score = 0;                             // inliers / votes, in (0, 1]; `found` is ordered by inliers
};

struct RecognitionResult {
  std::vector<Recognition> found;  // most inliers first; empty: no target in view
  int keypoints = 0;               // query points detected
  int matches = 0;                 // ratio-test matches over all targets
  int candidates = 0;              // targets verified
  double detect_ms = 0;            // smoothing + detection
  double describe_ms = 0, search_ms = 0, verify_ms = 0;
  double total_ms() const { return detect_ms + describe_ms + search_ms + verify_ms; }
};

// Cost: Add and Remove only store/drop the model (O(model) copy); the index
// over all targets is rebuilt lazily, once, on the next Recognize (or
// memory_bytes) after a change — an FFVA build, O(N log N) in the total number
// of centres (a few ms for tens of targets). So adding many targets and then
// recognising builds once.
//
// Thread safety: concurrent Recognize calls are safe (the lazy build is
// guarded by a mutex); Add/Remove must not run concurrently with anything.
class Recognizer {
 public:
  explicit Recognizer(const RecognizerOptions& options = {});
  ~Recognizer();
  Recognizer(Recognizer&&) noexcept;
  Recognizer& operator=(Recognizer&&) noexcept;

  // Copies the model. Throws Error(kInvalidArgument) for an empty or duplicate
  // id, or if the model's query-side feature settings (smooth_sigma,
  // patch_size, dims, orient, orientation_radius, detector thresholds) differ
  // from those of the targets already added; Error(kBadModel) for an
  // inconsistent model. Targets keep their order of addition.
  void Add(const std::string& id, const Model& model);
  // False if there is no such id.
  bool Remove(const std::string& id);
  bool Contains(const std::string& id) const;
  std::size_t size() const { return targets_.size(); }
  std::vector<std::string> ids() const;
  const RecognizerOptions& options() const { return options_; }

  // Finds the targets in an 8-bit grayscale frame (Error(kInvalidArgument)
  // otherwise). With no targets, returns an empty result without looking.
  RecognitionResult Recognize(const cv::Mat& gray) const;

  // Temporal focus (thesis §6.3.1): looks for one target only, with that
  // target's own Matcher (its own small index, the half-resolution retry);
  // much cheaper than Recognize when the target is known to be in view.
  // Throws Error(kInvalidArgument) for an unknown id. The Matcher is built on
  // first use and kept.
  RecognitionResult RecognizeOne(const cv::Mat& gray, const std::string& id) const;

  // Bytes held: the index (with its copy of the centres) plus the models.
  std::size_t memory_bytes() const;

 private:
  struct Target {
    std::string id;
    Model model;
  };
  void EnsureIndex() const;

  RecognizerOptions options_;
  std::vector<Target> targets_;
  // Built lazily from targets_ (see above).
  mutable std::unique_ptr<std::mutex> mutex_;
  mutable std::unique_ptr<KnnIndex> index_;
  mutable bool dirty_ = true;
  mutable std::vector<std::int32_t> label_target_;    // global location id -> target index
  mutable std::vector<std::int32_t> target_offset_;   // target index -> first global location id
  mutable std::map<std::string, std::shared_ptr<const Matcher>> focus_;  // RecognizeOne's matchers
};

}  // namespace mvkp
