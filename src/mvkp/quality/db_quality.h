// Quality of a target database as a whole (`mvkp quality DB`, the admin
// page's quality panel): each exhibit's score, as `mvkp quality` gives its
// stored image, and the pairs of exhibits that confuse each other.
//
// Look-alikes are found by recognition, as a visitor's phone would meet them:
// each exhibit's stored image, and `synthetic_views` camera views of it on a
// busy backdrop, are recognised against a Recognizer holding every OTHER
// exhibit (the exhibit itself is taken out, so its own points cannot hide a
// near-duplicate behind the ratio test). Any exhibit found there is a
// look-alike. Per exhibit that is 1 + synthetic_views recognitions plus one
// index rebuild over the others, a small part of the score's assessment
// (seconds per exhibit; QualityOptions::test_views sets that cost).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/db/target_store.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"

namespace mvkp {

struct DatabaseQualityOptions {
  QualityOptions quality;          // per-exhibit score, as `mvkp quality` computes it
  bool score = true;               // false: look-alike pairs only (skips the seconds-long assessments)
  RecognizerOptions recognizer;    // how look-alikes are searched (kExact, as `mvkp recognize` and serve)
  int synthetic_views = 2;         // camera views per exhibit besides its stored image (0..16)
  std::uint64_t seed = 11;         // the synthetic views
  // Stored images above this many pixels are decoded reduced (JPEG: 1/2, 1/4
  // or 1/8), as the guide service decodes them; others are refused.
  std::int64_t max_pixels = 100'000'000;
  std::string name;                // names the database in errors and in the report ("": its path)
  // Optional: replaces AssessTarget(gray, quality) for one exhibit (a caller's
  // cache, or a CPU gate). Called only when `score`.
  std::function<QualityReport(const TargetInfo& info, const cv::Mat& gray)> assess;
  // Optional: called after each exhibit with (done, total).
  std::function<void(int, int)> progress;
  void Check() const;  // throws Error(kInvalidArgument)
};

// One exhibit's part of the report.
struct ExhibitQuality {
  TargetInfo info;
  bool assessed = false;   // `quality` holds its score (false: not scored, or `error`)
  QualityReport quality;   // as AssessTarget reports it for the stored image
  std::string error;       // why it could not be assessed or probed ("" if fine)
  double quality_ms = 0;   // time of the score (0 when it came from `assess`'s cache)
  double probe_ms = 0;     // time of its look-alike search
};

// Exhibit `a` seen as exhibit `b`: b was found in `found_in` of a's `probes`
// recognitions (stored image + synthetic views), with at most `inliers`
// inliers. Reported once per ordered pair; a mutual confusion gives two.
struct LookalikePair {
  std::string a, b;
  int found_in = 0, probes = 0;
  int inliers = 0;
};

struct DatabaseQualityReport {
  std::string db;
  std::vector<ExhibitQuality> exhibits;  // ordered by id
  std::vector<LookalikePair> pairs;      // most inliers first
  double ms = 0;                         // total time
};

// Assesses every exhibit of the target database at `db`. Throws Error(kIo) /
// Error(kBadModel) when `db` cannot be opened as a target database, and
// Error(kInvalidArgument) for bad options. An exhibit whose image or model
// cannot be read gets an `error` and the others go on.
DatabaseQualityReport AssessDatabase(const std::string& db, const DatabaseQualityOptions& options = {});

}  // namespace mvkp
