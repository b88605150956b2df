// OpenCV feature pipelines as a user would run them, for side-by-side runs:
// object features prepared once; per frame detectAndCompute, brute-force
// 2-NN, ratio test 0.8, RANSAC homography (3 px). Single thread.
#pragma once

#include <string>
#include <vector>

#include <opencv2/features2d.hpp>

namespace mvkp::cli {

struct BaselineResult {
  bool found = false;
  cv::Matx33d homography = cv::Matx33d::eye();
  std::vector<cv::Point2f> object_pts, query_pts;  // after the ratio test
  std::vector<std::uint8_t> inlier;
  int keypoints = 0;
  double ms = 0;  // per-frame cost: detect+describe the frame, match, RANSAC
};

class Baseline {
 public:
  // name: sift | orb | akaze | brisk | asift (AffineFeature over SIFT, FLANN matching)
  Baseline(const std::string& name, int max_features = 2000);
  const std::string& name() const { return name_; }
  void Prepare(const cv::Mat& object_gray);
  BaselineResult Frame(const cv::Mat& frame_gray) const;

 private:
  std::string name_;
  cv::Ptr<cv::Feature2D> f_;
  int norm_ = cv::NORM_L2;
  bool flann_ = false;
  std::vector<cv::KeyPoint> kobj_;
  cv::Mat dobj_;
};

// Reads a homography text file: 9 numbers, row-major (Oxford / HPatches style).
cv::Matx33d ReadHomography(const std::string& path);

// One line of a pair manifest (`img1 img2 H`, as `mvkp synth` writes and
// eval_pairs.py reads); relative paths are resolved against the manifest's
// folder, whose name becomes `set`. H may be "none".
struct ManifestPair {
  std::string img1, img2, h, set;
};
std::vector<ManifestPair> ReadManifest(const std::string& path);

}  // namespace mvkp::cli
