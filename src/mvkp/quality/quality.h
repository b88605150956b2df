// Target quality: how well an image will be recognised as a planar target,
// before it is deployed (RIFS, thesis §3.3 / SPEC §4, as a user-facing score).
//
// The image is assessed as a user will run it (issue 18): trained as given
// (no contrast stretch, no resizing beyond what `mvkp train` does), exactly as
// `mvkp train` would, and matched by the default Matcher against test frames
// over the envelope of `mvkp eval sweep`: pinhole-camera views of the target
// plane (apparent size 60-620 px at tilts up to 40 degrees, and 200-400 px at
// tilts up to 75), on busy procedural backdrops, with the sweep's lighting
// (target contrast down to 0.45), blur, noise and JPEG. The score combines
// the measured detection rate (60 points) with four structural factors (10
// points each, counted in full once the target is found in a third of the
// views), each reported with the points it costs, so the number explains itself:
//   stable points   eligible RIFS view tracks at the top training level
//                   (too few: fragile target)
//   distinctiveness how far each selected point's nearest look-alike is,
//                   relative to DS (repeated elements: tiles, brick, text)
//   texture         share of the image with usable gradient structure
//   coverage        share of the image's grid cells holding selected points
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/match/matcher.h"
#include "mvkp/synth/camera_view.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

namespace mvkp {

// The sweep's frames, rendered at 2x supersampling (not 4x) to keep the
// assessment within a few seconds.
inline CameraSceneOptions QualitySceneDefaults() {
  CameraSceneOptions s;
  s.supersample = 2;
  return s;
}

struct QualityOptions {
  int target_size = 320;     // the structural factors (texture, coverage) are measured at this longest side
  int test_views = 96;       // test frames for the detection rate (SE of the rate <= 0.051)
  std::uint64_t seed = 7;    // test views (training uses train.seed)
  double success_px = 5.0;   // a view counts as detected when the mean corner error is below this
  double min_contrast = 24;  // grey levels between the 0.5th and 99.5th percentile; below: uniform (score 0)
  // Weights of the score (sum 1): detection rate and the four factors.
  double w_detection = 0.6, w_stable = 0.1, w_distinct = 0.1, w_texture = 0.1, w_coverage = 0.1;
  // The four structural factors count in full once the (soft) detection rate
  // reaches half_rate, and proportionally less below: a target that is never
  // found scores near 0 however textured it looks.
  double half_rate = 0.3;
  // Where each factor reaches 1 (and below which it is reported as a reason).
  int good_stable_tracks = 300;
  double good_texture = 0.5;
  double good_coverage = 0.6;
  double good_distinct = 0.40;     // median nearest-look-alike distance / DS of a distinct target...
  double repeated_distinct = 0.15; // ...and of a tiled pattern (factor 0)
  double lookalike = 0.25;   // a location whose nearest other location is closer than this times DS has a twin
  TrainOptions train;        // the model as `mvkp train` would build it
  MatchOptions match;        // the frames searched as `mvkp match` would
  // Test frames: half over apparent size (longest side, log-uniform) at tilts
  // up to size_tilt, half over tilt (uniform in angle) at sizes tilt_size_*.
  double min_size = 60, max_size = 620, size_tilt = 40;
  double max_tilt = 75, tilt_size_min = 200, tilt_size_max = 400;
  CameraSceneOptions scene = QualitySceneDefaults();
  void Check() const;        // throws mvkp::Error(kInvalidArgument)
};

struct QualityFactor {
  std::string name;     // "detection", "stable_points", "distinctiveness", "texture", "coverage"
  double value = 0;     // raw measurement (rate, count or share)
  double factor = 0;    // normalised to [0, 1]
  double weight = 0;
  double points = 0;    // contribution to the score: 100 * weight * factor (* detection gate)
  double lost = 0;      // points its weakness costs; detection also carries what the gate takes from
                        // the others, so score + sum of lost = 100
};

struct QualityReason {
  std::string code;     // too_small, uniform, low_detection, few_stable_points, repeated_elements, low_texture, concentrated
  std::string message;  // one sentence a user can act on
  double lost = 0;      // score points attributed to it
};

struct QualityReport {
  int score = 0;                        // 0..100
  std::string verdict;                  // "excellent" (>= 80), "good" (>= 60), "fair" (>= 40), "poor"
  double detection_rate = 0;            // fraction of test frames found within success_px
  int test_views = 0;
  double median_error_px = 0;           // over detected views
  // Stable points: eligible view tracks of the top training level, which is
  // trained at train_side px (longest side; `mvkp train`: up to 640).
  // `mvkp db add` trains at 320 px (RecognitionTrainDefaults) and counts
  // the same tracks there, so its count of a small or plain image is lower.
  int eligible_tracks = 0, selected_tracks = 0;
  int train_side = 0;                   // 0 when the image could not be trained
  std::vector<QualityFactor> factors;
  std::vector<QualityReason> reasons;   // most costly first; empty for a flawless target
  std::vector<cv::Point2f> selected;    // selected view tracks, input-image pixels (best first)
  std::vector<cv::Point2f> rejected;    // eligible tracks not selected
  double ms = 0;
};

// Assesses an 8-bit grayscale image. Never throws for image content: a
// uniform or tiny image gets score 0 with the reason. Throws
// Error(kInvalidArgument) for an empty image or bad options.
QualityReport AssessTarget(const cv::Mat& gray, const QualityOptions& options = {});

// The image with selected features as white plus signs (thesis Fig. 3.15),
// rejected candidates as small grey dots, and the score in a corner.
cv::Mat DrawQuality(const cv::Mat& image, const QualityReport& report);

}  // namespace mvkp
