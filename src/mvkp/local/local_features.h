// Local-feature pipelines behind one interface, so that one evaluator can
// compare them: CDIKP, OpenCV's SIFT / ORB / AKAZE, and augmented features
// (thesis ch. 4) over SIFT or CDIKP. Each extracts keypoints + descriptors
// (timing detection, description and augmentation separately) and finds, for
// every keypoint of a query image, its two nearest keypoints in an object
// image under the method's own distance, for the ratio test.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "mvkp/augment/augment.h"
#include "mvkp/cdikp/cdikp.h"

namespace mvkp {

struct LocalFeatureOptions {
  int max_features = 0;        // SIFT / CDIKP / ORB keypoint cap (0: SIFT and CDIKP keep all, ORB 5000)
  CdikpOptions cdikp;          // CDIKP descriptor (and its SIFT detector) settings
  AugmentOptions augment;      // aug-*: sub-image size, tie handling
  AugmentMetric metric = AugmentMetric::kSpearman;  // aug-*: similarity used for matching
  void Check() const;
};

struct LocalFeatures {
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;   // base descriptors (CV_32F, or CV_8U binary for ORB / AKAZE)
  cv::Mat codes;         // aug-*: ordinal codes, one row per keypoint; empty otherwise
  double detect_ms = 0, describe_ms = 0, augment_ms = 0;
};

// For one query keypoint: its nearest and second-nearest object keypoints.
struct NearestTwo {
  int query = -1, best = -1, second = -1;  // second = -1 when the object has one keypoint
  float d1 = 0, d2 = 0;                    // distances in the method's metric (d2 = inf without a second)
};

class LocalFeatureMethod {
 public:
  // name: cdikp | sift | orb | akaze | aug-sift | aug-cdikp. Throws
  // Error(kInvalidArgument) for any other name.
  static std::unique_ptr<LocalFeatureMethod> Create(const std::string& name, const LocalFeatureOptions& options = {});
  virtual ~LocalFeatureMethod() = default;

  const std::string& name() const { return name_; }
  // Bytes per stored descriptor (codes for aug-*).
  virtual int descriptor_bytes() const = 0;
  // 8-bit grayscale image in; an image without keypoints gives empty sets.
  virtual LocalFeatures Extract(const cv::Mat& gray) const = 0;
  // Two nearest object keypoints of every query keypoint (ties by smaller index).
  virtual std::vector<NearestTwo> Match(const LocalFeatures& object, const LocalFeatures& query) const = 0;

 protected:
  explicit LocalFeatureMethod(std::string name) : name_(std::move(name)) {}

 private:
  std::string name_;
};

// Every name Create() accepts, in a stable order.
const std::vector<std::string>& LocalFeatureMethodNames();

}  // namespace mvkp
