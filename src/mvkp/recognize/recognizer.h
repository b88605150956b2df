// Multi-target recognition (thesis ch. 6, SPEC §8): which of many trained
// targets are in a frame, if any.
//
// Two searches, both ending in the same verification:
//
// kWords (what scales to 10 000 targets). Each target is stored
// compactly: its most stable object locations (RecognizerOptions::
// max_locations), and for each location the few visual words its k-means
// centres fall in most often (words_per_location), each with a Hamming
// signature (vocabulary.h). The postings (target, location, signature) of all
// targets sit in one inverted file, one list per word, so adding or removing a
// target touches only its own postings. Per frame each query descriptor is
// quantised to its nearest word(s); every posting of those words within
// max_hamming signature bits is a tentative correspondence and a vote for its
// target (one per query point per target).
//
// kExact (the thesis's design; the default, best recall on small sets). One FFVA index
// holds the k-means centres of ALL targets, labelled by global location; each
// query descriptor gets its nearest centre and the nearest centre of a
// DIFFERENT location, and the ratio test decides whether it votes.
//
// Verification: up to max_candidates targets with at least min_votes votes
// (most votes first) are verified by a robust homography over their own
// correspondences, as Matcher does (same estimator, plausible-outline check,
// fixed RNG state, so results are deterministic); those with >= min_inliers
// inliers (distinct query points) are reported, most inliers first. Several
// targets can be found in one frame; "no target" is an empty `found`.
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

#include "mvkp/describe/features.h"
#include "mvkp/index/knn_index.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/recognize/vocabulary.h"
#include "mvkp/train/trainer.h"

namespace mvkp {

enum class RecognizerSearch { kWords, kExact };

// Recognition looks at 1000 query points, not Matcher's 500: several
// targets share a frame, often small. On the gallery scenes of
// docs/gallery.md recall is 89.4 / 95.6 / 96.3 % with 500 / 750 / 1000 points
// (23.6 / 23.3 / 29.1 ms median per frame). And each target gets its own
// ratio (thesis §6.3.1): 40 matches wanted, ratios under 0.7 always kept,
// none over 0.92: recall 98.2 %, no pose off by 10 px, still no false
// detection in 300 no-target frames (the first setting tried).
//
// Recognition searches every frame for every target, and most frames of a
// guide or a video show none: the single-target cascade's last stages (the
// frame upsampled for tiny targets, simulated steep views), which run on
// every frame where nothing is found, are off here (MatchOptions for them).
inline MatchOptions RecognitionMatchDefaults() {
  MatchOptions m;
  m.max_points = 1000;
  m.dynamic_goal = 40;
  m.ratio_min = 0.7f;
  m.ratio_max = 0.92f;
  m.upsample_points = 0;
  m.tilt_directions = 0;
  return m;
}

// How `mvkp db add`/`import`, the server's admin API and Python's
// Database.add train exhibits: at 320 px (exhibits are matched at a few
// hundred pixels in guide frames; the models stay half as large as at 640),
// otherwise as `mvkp train` does: the training pyramid then covers paintings
// down to a sixth of a 640-px frame (before issue 18 this took view scales
// down to 0.25 instead).
inline TrainOptions RecognitionTrainDefaults() {
  TrainOptions t;
  t.max_object_side = 320;
  return t;
}

struct RecognizerOptions {
  MatchOptions match = RecognitionMatchDefaults();  // query points, geometry, robust estimator, RANSAC threshold; kExact: ratio and index kind
  // kExact is the default: better recall per frame on tens to hundreds of
  // targets; kWords for thousands (speed and memory; see the README's table).
  RecognizerSearch search = RecognizerSearch::kExact;
  // kWords: how a target is stored (applied at Add) ...
  int max_locations = 150;      // most stable object locations kept per target (<= 256)
  int words_per_location = 5;   // postings per location: the words its centres fall in most often
  // ... and searched.
  int query_words = 2;          // nearest words looked up per query descriptor
  int max_hamming = 6;          // signature bits (of 20) that may differ for a tentative correspondence
  // Keep each target's full model so RecognizeOne can use the target's own
  // Matcher (its exact index, half-resolution retry): about 300 KB per target
  // instead of a few KB. kExact always keeps the models.
  bool keep_models = false;
  // kExact: 0 compares each query descriptor with every target's centres
  // (exact, FFVA). N > 0 compares it only with the centres that fall in its N
  // nearest vocabulary words (an inverted file over the vocabulary, IvfIndex):
  // approximate, and many times faster from tens of targets on. Measured
  // (mvkp_recognize_scale, mean ms per frame and recall@1 of 80): 100
  // targets, exhaustive 106 ms 71/80, 4 words 9.2 ms 71/80, 8 words 11.4 ms
  // 70/80; 1000 targets, exhaustive 1134 ms 64/80, 4 words 51 ms 61/80, 8
  // words 97 ms 64/80. Gallery scenes of docs/gallery.md (28 targets): recall
  // 98.2 / 97.4 / 97.8 % (exhaustive / 4 / 8), no false detection in any.
  int probe_words = 8;
  int max_candidates = 5;  // targets verified per frame, most votes first
  int min_votes = 8;       // ratio-test matches a target needs to be verified
  int min_inliers = 12;    // RANSAC inliers to accept a target
  void Check() const;

  // kWords with its own query budget: 600 points, not 1000. More points add
  // chance votes as fast as true ones at thousands of targets
  // (mvkp_recognize_scale, 1000 targets: recall 50/80 at 1000 points,
  // 55/80 at 600, and 20 against 15 ms per frame).
  static RecognizerOptions Words() {
    RecognizerOptions o;
    o.search = RecognizerSearch::kWords;
    o.match.max_points = 600;
    // The strongest points, not a share per cell: spreading 600 points over
    // the frame adds chance votes as fast as true ones (recognizer tests).
    o.match.grid_share = 0;
    return o;
  }
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

// Cost (kWords): Add encodes the model (a few ms) and appends its postings;
// Remove erases them (a pass over the inverted file). kExact: Add and Remove
// only store/drop the model; the index over all targets is rebuilt lazily, once,
// on the next Recognize (or memory_bytes) after a change.
//
// Thread safety: concurrent Recognize / RecognizeOne calls are safe (lazy
// builds are guarded by a mutex); Add/Remove must not run concurrently with
// anything.
class Recognizer {
 public:
  // kWords uses `vocabulary` (DefaultVocabulary() if null; it must outlive the
  // recogniser) whose dims must equal the models'.
  explicit Recognizer(const RecognizerOptions& options = {}, const Vocabulary* vocabulary = nullptr);
  ~Recognizer();
  Recognizer(Recognizer&&) noexcept;
  Recognizer& operator=(Recognizer&&) noexcept;

  // Encodes (kWords) or copies (kExact) the model. Throws
  // Error(kInvalidArgument) for an empty or duplicate id, or if the model's
  // query-side feature settings (smooth_sigma, patch_size, dims, orient,
  // orientation_radius, detector thresholds) differ from those of the targets
  // already added or (kWords) its dims from the vocabulary's;
  // Error(kBadModel) for an inconsistent model. Targets keep their order of
  // addition in ids().
  void Add(const std::string& id, const Model& model);
  // kWords: the compact form Add stores for `model` (a few KB, CRC-checked,
  // tied to the vocabulary and the word settings), and adding a target from
  // it, so a database can keep it beside the model and a recogniser load
  // thousands of targets without decoding their models. AddEncoded throws
  // Error(kBadModel) for a corrupt encoding or one made with another
  // vocabulary or word settings (encode the model again then), and the
  // errors of Add. Targets added this way have no model: RecognizeOne uses
  // their postings even with keep_models.
  std::vector<std::uint8_t> Encode(const Model& model) const;
  void AddEncoded(const std::string& id, const std::uint8_t* data, std::size_t size);
  // False if there is no such id.
  bool Remove(const std::string& id);
  bool Contains(const std::string& id) const;
  std::size_t size() const { return ids_.size(); }
  std::vector<std::string> ids() const { return ids_; }
  const RecognizerOptions& options() const { return options_; }

  // Finds the targets in an 8-bit grayscale frame (Error(kInvalidArgument)
  // otherwise). With no targets, returns an empty result without looking.
  RecognitionResult Recognize(const cv::Mat& gray) const;
  // As Recognize, verifying up to `max_candidates` targets instead of
  // options().max_candidates (1..100000, Error(kInvalidArgument) otherwise):
  // room for new targets when some are already known to be in view, so that
  // those do not take every place (the guide service adds its ?prev= ids).
  RecognitionResult Recognize(const cv::Mat& gray, int max_candidates) const;

  // Temporal focus (thesis §6.3.1): looks for one target only; cheaper than
  // Recognize and more sensitive (that target's votes need not stand out
  // among others'). With the full model kept (kExact, or keep_models) it uses
  // the target's own Matcher, built on first use and kept; otherwise only
  // that target's postings. Throws Error(kInvalidArgument) for an unknown id.
  RecognitionResult RecognizeOne(const cv::Mat& gray, const std::string& id) const;

  // Bytes held for the targets: postings, locations, ids, kept models and
  // (kExact) the index. The shared vocabulary is not included: see
  // shared_bytes().
  std::size_t memory_bytes() const;
  // Bytes shared by all targets whatever their number (the vocabulary and the
  // inverted file's per-word headers).
  std::size_t shared_bytes() const;
  // Releases the inverted file's spare capacity (kWords); call after a bulk
  // load, since lists grow geometrically while targets are added.
  void ShrinkToFit();
  // kExact: builds the search index over the current targets now; otherwise
  // the first Recognize after a change builds it (a server calls this before
  // it swaps a reloaded recogniser in, so no request waits for the build).
  void Prepare() const;

 private:
  struct Impl;
  // Both searches; only_slot >= 0 restricts kWords to one target (focus).
  RecognitionResult Search(const cv::Mat& gray, std::int64_t only_slot, const RecognizerOptions& o) const;
  // What a frame's search keeps between the first pass and the
  // half-resolution retry, so the retry searches only the new points.
  struct SearchState;
  void VoteAndVerify(const Features& f, std::int64_t only_slot, const RecognizerOptions& o, SearchState& state,
                     RecognitionResult& r) const;

  std::unique_ptr<Impl> impl_;
  RecognizerOptions options_;
  std::vector<std::string> ids_;  // order of addition
};

}  // namespace mvkp
