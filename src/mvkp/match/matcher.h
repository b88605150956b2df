// MVKP query (thesis §3.2.2-3.2.3, SPEC §3): detect and describe the frame
// with the model's own feature settings, find for each query descriptor the
// nearest model centre and the nearest centre of a DIFFERENT object location,
// keep the pair if d1/d2 < ratio (optionally steering the ratio toward a goal
// count as the frame is processed), and verify geometrically with RANSAC.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/describe/features.h"
#include "mvkp/index/knn_index.h"
#include "mvkp/model/model.h"

namespace mvkp {


enum class GeometryModel { kHomography, kAffine };

// Robust estimators from OpenCV's calib3d. kAccurate (USAC with graph-cut
// local optimisation) measured best overall: more frames within 5 px than
// classic RANSAC and ~2.5x faster on outlier-heavy frames (README).
enum class RobustMethod { kRansac, kFast, kAccurate, kMagsac };

struct MatchOptions {
  int max_points = 500;          // strongest query points (thesis: ~500)
  int half_res_points = 250;     // when not found at full resolution, retry with this many more
                                 // points from half resolution (targets larger than trained); 0: off
  int retry_below_inliers = 40;  // also retry at half resolution when found with fewer inliers
  float ratio = 0.85f;           // distance-ratio test on distances (not squared); SPEC: 0.85 with orientation
  int dynamic_goal = 0;          // > 0: steer the ratio toward this many kept matches (thesis §3.2.3)
  int dynamic_checks = 10;       // how often the ratio is adjusted while processing the frame
  float ratio_min = 0.6f;        // bounds for the dynamic ratio
  float ratio_max = 0.95f;
  GeometryModel geometry = GeometryModel::kHomography;
  RobustMethod robust = RobustMethod::kAccurate;
  double ransac_threshold = 4.0; // reprojection error for an inlier (query pixels)
  int ransac_iterations = 2000;
  double ransac_confidence = 0.995;
  int min_inliers = 10;          // fewer inliers: the target is not found
  std::string index = "exact";   // descriptor search: exact (FFVA), approx (thesis block distance), brute
  void Check() const;
};

struct Correspondence {
  cv::Point2f object;  // object-image pixels
  cv::Point2f query;   // query-frame pixels
  float distance = 0;  // descriptor distance to the nearest centre (L2, not squared)
  int location = -1;   // object location id in the model
  bool inlier = false; // RANSAC inlier
};

struct MatchTiming {
  double smooth_ms = 0, detect_ms = 0, describe_ms = 0, search_ms = 0, verify_ms = 0;
  double total() const { return smooth_ms + detect_ms + describe_ms + search_ms + verify_ms; }
};

struct MatchResult {
  bool found = false;
  cv::Matx33d homography = cv::Matx33d::eye();  // maps object pixels to query pixels (valid if found)
  std::array<cv::Point2f, 4> outline{};         // object corners in the query frame (valid if found)
  std::vector<Correspondence> matches;          // after the ratio test, before RANSAC
  int inliers = 0;
  int keypoints = 0;                            // query points detected
  float final_ratio = 0;                        // ratio in force at the end (differs when dynamic)
  MatchTiming time;
};

class Matcher {
 public:
  // Builds the search index over the model's descriptors. The model is copied.
  Matcher(const Model& model, const MatchOptions& options = {}, std::unique_ptr<KnnIndex> index = nullptr);

  // Finds the model's target in an 8-bit grayscale frame.
  MatchResult Match(const cv::Mat& gray) const;

  const Model& model() const { return model_; }
  const MatchOptions& options() const { return options_; }

 private:
  void SearchAndFilter(const Features& f, std::size_t first, MatchResult& r) const;
  void Verify(MatchResult& r) const;

  Model model_;
  MatchOptions options_;
  std::unique_ptr<KnnIndex> index_;
};

// Robust fit of object -> query point pairs with the estimator, geometry and
// thresholds of `options` (USAC / RANSAC homography, or affine). Empty
// `homography` when no model was found; `mask` marks the inliers.
struct GeometryFit {
  bool ok = false;
  cv::Matx33d homography = cv::Matx33d::eye();
  std::vector<std::uint8_t> mask;
  int inliers = 0;
};
GeometryFit FitGeometry(const std::vector<cv::Point2f>& object, const std::vector<cv::Point2f>& query,
                        const MatchOptions& options);

// Where H puts the object's corners (0,0), (w-1,0), (w-1,h-1), (0,h-1).
std::array<cv::Point2f, 4> ProjectOutline(const cv::Matx33d& H, int width, int height);

// The feature settings a query frame must be processed with for a model
// trained with `params`, keeping the `max_points` strongest points.
FeatureOptions QueryFeatureOptions(const ModelParams& params, int max_points);

// Mean distance (pixels) between where two homographies put the four corners
// (0,0), (w-1,0), (w-1,h-1), (0,h-1) of an image of `size`: the HPatches-style
// corner error that eval_pairs.py and `mvkp eval` report. +inf if not finite.
double MeanCornerError(const cv::Matx33d& a, const cv::Matx33d& b, cv::Size size);

// True if the quadrilateral is convex, not self-intersecting, and of area >= min_area.
bool IsPlausibleOutline(const std::array<cv::Point2f, 4>& quad, double min_area = 64.0);

}  // namespace mvkp
