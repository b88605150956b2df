// Patch descriptors by Walsh–Hadamard projection, and the one feature
// pipeline that training and query share (so that both see identical
// smoothing, detection and description).
//
// A keypoint's patch is the patch_size x patch_size square centred on it,
// rotated by the keypoint's orientation (the intensity-centroid angle over a
// disc, as ORB does; SPEC §3 measured this as the change that brings MVKP level
// with SIFT). Because the first K Walsh–Hadamard kernels only see the patch's
// grid of b x b block sums (see wht.h), the describer never cuts the full
// patch: it box-filters the frame once and samples the grid's block means at
// the rotated block centres, then projects. For an unrotated patch at integer
// coordinates this equals projecting the cut patch exactly (tested).
//
// Descriptors are contrast-normalised: block means are divided by their
// standard deviation over the patch (DC is dropped, so the offset does not
// matter) and scaled by 1/grid, which makes the kernels orthonormal.
#pragma once

#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/detect/detector.h"
#include "mvkp/wht/wht.h"

namespace mvkp {

namespace internal {
struct DiscTable;
}

struct DescriberOptions {
  int patch_size = 32;          // k: patch side in pixels (thesis: 32)
  int dims = 20;                // K: Walsh–Hadamard kernels kept, DC excluded (thesis: 20)
  bool orient = true;           // rotate patches to their intensity-centroid angle
  int orientation_radius = 15;  // disc radius for the intensity centroid (pixels)
  void Check() const;
};

class Describer {
 public:
  explicit Describer(const DescriberOptions& options = {});
  int dims() const { return projector_.dims(); }
  const DescriberOptions& options() const { return options_; }

  // smoothed: 8-bit grayscale frame. Sets keypoints[i].angle (0 when orient is
  // off) and writes keypoints.size() x dims() floats, row-major, to out.
  void Compute(const cv::Mat& smoothed, std::vector<Keypoint>& keypoints, float* out) const;

  // The same in two steps, for callers that describe a frame's points in
  // several batches: Prepare computes the per-frame part (the block means,
  // CV_32F) once; Compute with it describes any subset, each point exactly
  // as the one-step Compute would.
  cv::Mat Prepare(const cv::Mat& smoothed) const;
  void Compute(const cv::Mat& smoothed, const cv::Mat& prepared, std::vector<Keypoint>& keypoints, float* out) const;

 private:
  DescriberOptions options_;
  wht::Projector projector_;
  std::shared_ptr<const internal::DiscTable> disc_;  // the orientation disc (internal/orient_kernels.h)
};

struct FeatureOptions {
  float smooth_sigma = 1.0f;  // Gaussian smoothing before detection (thesis §3.2.1)
  DetectorOptions detector;
  DescriberOptions describer;
  void Check() const;
};

struct Features {
  std::vector<Keypoint> keypoints;
  cv::Mat descriptors;  // keypoints.size() x dims, CV_32F
  double smooth_ms = 0, detect_ms = 0, describe_ms = 0;
};

// The frame scaled by f: area-averaged to round(f * size) (at least 1x1)
// when f < 1, the frame itself (not copied) otherwise. Used where large
// frames are searched at a working size.
cv::Mat ScaleFrameDown(const cv::Mat& gray, double f);

// Smoothing and detection only (ExtractFeatures without the description),
// for callers that describe only some of the points (Describer::Prepare).
struct DetectedFrame {
  cv::Mat smoothed;  // the frame the describer reads
  std::vector<Keypoint> keypoints;
  double smooth_ms = 0, detect_ms = 0;
};
DetectedFrame DetectFeatures(const cv::Mat& gray, const FeatureOptions& options, const cv::Mat& mask = cv::Mat());

// Smooths, detects and describes. Detection is restricted to mask != 0 if a
// mask (CV_8UC1, same size) is given.
Features ExtractFeatures(const cv::Mat& gray, const FeatureOptions& options, const cv::Mat& mask = cv::Mat());

}  // namespace mvkp
