// MVKP training (thesis §3.2.1, SPEC §2): from ONE object image, synthesise
// views, detect points in each, map them back to object coordinates, group
// them into view tracks, keep the most stable object locations, and describe
// each by k-means centres of its Walsh–Hadamard descriptors.
//
// Beyond the thesis, the envelope a camera sees (issue 18):
// - a training pyramid: the target is trained at several resolutions, a
//   factor 2 apart (640, 320, 160, 80 px for a large target), each level with
//   its own views, tracks and locations, all in one model. A level's views
//   cover half to once its size, so together the levels cover targets from
//   `min_apparent_size` up to the top level's size with one query level;
// - camera-model views: homographies of the target plane seen by a pinhole
//   camera (synth/camera_view.h) at tilts up to `max_tilt_deg`, all azimuths,
//   sampled ASIFT-style (uniform in the tilt factor t = 1/cos(tilt) above
//   40°, so steep views get the share their larger appearance change needs),
//   rendered with a directional anti-aliasing blur along the compressed axis.
// ViewModel::kAffine with levels = 1 is the thesis design (affine views over
// lambda in [min_scale, max_scale], one resolution).
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/model/model.h"
#include "mvkp/rifs/rifs.h"

namespace mvkp {

// How view tracks are ranked before the best are kept.
enum class Selection {
  kStability,  // by stability SS over the general views (the MVKP baseline; no rotation views)
  kRifs,       // by the RIFS final score FRS over general + rotation views (SPEC §4); alpha 0 = SS only
};

enum class ViewModel {
  kMixed,   // per level: the thesis's affine views plus pinhole-camera views at steep tilts (default)
  kAffine,  // the thesis's affine views A = R(theta) R(-phi) diag(l1, l2) R(phi) only
  kCamera,  // pinhole-camera views only, tilts 0..max_tilt_deg (frontal_share of them at <= 40 degrees)
};

struct TrainOptions {
  ViewModel view_model = ViewModel::kMixed;
  int views = 100;            // N_V synthetic views per pyramid level (thesis: 50-100); kMixed: the affine ones
  int camera_views = 40;      // kMixed: pinhole-camera views per level at tilts camera_min_tilt..max_tilt_deg
  double camera_min_tilt = 50;  // kMixed: the camera views' shallowest tilt (degrees)
  int locations = 200;        // object locations kept at the top level, best ranked first (thesis: 100-200)
  double level_locations = 0.5;  // each smaller level keeps this fraction of the previous level's count
  int levels = 0;             // training pyramid levels, a factor 2 apart (0: auto, down to min_apparent_size)
  int min_apparent_size = 40; // auto levels: the smallest longest side (query pixels) to cover
  int min_level_size = 48;    // no level smaller than this (longest side, pixels)
  double level_min_scale = 0.5;  // kCamera: longest side from this ...
  double level_max_scale = 1.0;  // ... to this times the level's (log-uniform); kMixed: min_scale..max_scale
  double max_tilt_deg = 80;   // camera views: steepest tilt of the target plane
  double frontal_share = 0.35;  // camera views: share at tilts <= 40 degrees (uniform in angle)
  double keep_fraction = 0;   // > 0: keep this fraction of the eligible tracks instead (thesis: 0.3)
  Selection select = Selection::kStability;  // RIFS did not measure better (README, "RIFS")
  double alpha = 0.5;         // RIFS weight of the ranking score (0: stability only)
  int rotation_views = 72;    // RIFS only: rotation-dominant views (every 360/n degrees), used for scoring only
  int min_stability = 0;      // L_SS: tracks in fewer scoring views are dropped (0: max(3, views/20))
  // Which views' descriptors give a track's mean, DS and VS (SS always counts
  // all views). kAll is SPEC §4 to the letter; kRotation measures only how a
  // point's descriptor varies when rotated (the thesis's argument against
  // boundary points); kGeneral only the views the model is built from.
  enum class StatsViews { kAll, kRotation, kGeneral } stats_views = StatsViews::kAll;
  int clusters = 20;          // k-means centres per location (thesis: 10-20)
  int kernels = 20;           // Walsh–Hadamard kernels = descriptor dims (thesis: 20)
  int patch = 32;             // patch side in pixels (thesis: 32)
  std::uint64_t seed = 42;    // drives view sampling, view noise and k-means
  double min_scale = 0.4;     // affine views: lambda range (thesis: [0.4, 1.6])
  double max_scale = 1.6;
  int points_per_view = 600;  // strongest detections kept per view
  float track_radius = 2.0f;  // a detection joins a location within this many view pixels
  float view_noise = 2.0f;    // Gaussian noise sigma added to each view (grey levels)
  float view_blur = 1.0f;     // each view is blurred with a sigma drawn from [0, view_blur] (beyond the thesis: measured gain on blurred and held-out views)
  bool orient = true;         // orientation-normalised patches (SPEC §3); false = thesis-literal
  float smooth_sigma = 1.0f;  // Gaussian smoothing before detection
  int max_object_side = 640;  // larger targets are trained at this size (0: never downscale)
  int min_locations = 12;     // fewer stable locations than this: too little texture to train
  int kmeans_iterations = 10;
  // Called after each view with (views done, views total); may be empty.
  std::function<void(int, int)> progress;
  void Check() const;         // throws mvkp::Error(kInvalidArgument)
};

// One view track of the training, as `mvkp train --explain` prints it.
struct TrackReport {
  float x = 0, y = 0;  // input-image pixels
  int level = 0;       // pyramid level (0: the largest)
  TrackScore score;    // SS counts general and rotation views
  int general = 0;     // detections in the general views (the k-means samples)
  int rank = -1;       // 0 = best; -1 when not eligible (SS < L_SS)
  bool kept = false;   // became a model location
};

struct TrainReport {
  int general_views = 0, rotation_views = 0, min_stability = 0;  // per level (general: affine + camera views)
  Selection select = Selection::kRifs;
  double alpha = 0;
  int candidates = 0, eligible = 0, kept = 0;
  double scale_to_input = 1;   // input pixels per training pixel (top level)
  std::vector<int> level_sizes;    // longest side of each pyramid level (pixels)
  std::vector<int> level_kept;     // locations kept per level
  std::vector<TrackReport> tracks;  // ranked first (by rank), then the ineligible ones
  double views_ms = 0, score_ms = 0, kmeans_ms = 0, total_ms = 0;
};

const char* SelectionName(Selection s);  // "stability" | "rifs"

// Longest side of each training pyramid level for a target trained at
// `top_side` (its longest side after max_object_side): halving while the
// level's smallest views are larger than min_apparent_size and the level is
// at least min_level_size; one level for affine views unless `levels` is set.
std::vector<int> TrainingLevelSizes(int top_side, const TrainOptions& options);

// Trains a model from an 8-bit grayscale object image. Throws
// Error(kNoTexture) when the image has too few stable interest points. If
// `report` is given it receives every view track's scores.
Model Train(const cv::Mat& object_gray, const TrainOptions& options = {}, TrainReport* report = nullptr);

}  // namespace mvkp
