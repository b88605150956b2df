// Matching two images with a LocalFeatureMethod (ratio test + RANSAC
// homography), and the Mikolajczyk–Schmid style evaluation of a pair with a
// known homography: correct / total matches over a sweep of ratio thresholds,
// precision and recall (thesis Fig. 4.5).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/local/local_features.h"

namespace mvkp {

struct PairMatch {
  cv::Point2f object, query;  // image-1 and image-2 pixels
  float distance = 0;
  bool inlier = false;
};

struct PairMatchResult {
  bool found = false;
  cv::Matx33d homography = cv::Matx33d::eye();  // image 1 -> image 2 (valid if found)
  std::vector<PairMatch> matches;               // after the ratio test, before RANSAC
  int inliers = 0;
  double verify_ms = 0;
};

struct PairMatchOptions {
  double ratio = 0.8;            // keep a match when d1 < ratio * d2
  double ransac_px = 3.0;        // RANSAC reprojection threshold (image-2 pixels)
  int min_inliers = 8;           // fewer: not found
  void Check() const;
};

// Ratio test over `nearest` (from method.Match(object, query)), then a RANSAC
// homography. Deterministic (cv::findHomography with a fixed RNG state).
PairMatchResult MatchPair(const LocalFeatures& object, const LocalFeatures& query, const std::vector<NearestTwo>& nearest,
                          const PairMatchOptions& options = {});

struct RatioPoint {
  double ratio = 0;
  int matches = 0;   // query keypoints passing the ratio test
  int correct = 0;   // ... whose object keypoint maps within eps of it under the true homography
};

struct PairEvaluation {
  int correspondences = 0;  // object keypoints with a query keypoint within eps of their true image (recall's denominator)
  std::vector<RatioPoint> sweep;
};

// The ten thresholds of the evaluation: 0.50, 0.55, ..., 0.95.
std::vector<double> DefaultRatioSweep();

// H maps image-1 (object) pixels to image-2 (query) pixels; query_size bounds
// where a correspondence can exist.
PairEvaluation EvaluatePair(const LocalFeatures& object, const LocalFeatures& query, const std::vector<NearestTwo>& nearest,
                            const cv::Matx33d& H, cv::Size query_size, const std::vector<double>& ratios,
                            double eps_px = 3.0);

}  // namespace mvkp
