// CDIKP: a scale- and rotation-invariant 20-D descriptor (thesis §3.4.1, SPEC §5),
// usable wherever OpenCV takes a cv::Feature2D.
//
// Keypoints come from OpenCV's SIFT detector (DoG extrema with scale and
// dominant orientation). For each keypoint a canonical patch_size x
// patch_size patch is sampled, centred on the keypoint, rotated by its
// orientation and scaled so that the patch side covers
// scale_factor x keypoint.size image pixels. The patch is projected on the
// first `dims` Walsh–Hadamard kernels (DC dropped, mvkp::wht::Projector) and
// the result is L2-normalised: with DC gone the descriptor ignores an
// additive brightness change, and the normalisation a gain change. Compare
// descriptors with cv::NORM_L2.
//
// Geometry. KeyPoint::angle is in degrees, measured in image coordinates (x
// right, y down), as OpenCV's SIFT reports it; the patch's +x axis points
// along (cos angle, sin angle) in the image. A keypoint with angle < 0
// (OpenCV's "no orientation") is described upright.
//
// Anti-aliasing. Patch pixels are spaced s = scale_factor * size / patch_size
// image pixels apart. The patch is sampled bilinearly from level
// L = floor(log2 s) of a 2x Gaussian pyramid (cv::pyrDown, level 0 = the
// image), where the sample spacing is in [1, 2) level pixels; below s = 1
// level 0 is interpolated. The Walsh–Hadamard kernels then only see block
// sums of the patch (see wht.h), a further low-pass.
//
// Borders. Patches that reach outside the image replicate its border pixels,
// so compute() keeps every keypoint it is given, in order.
#pragma once

#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "mvkp/wht/wht.h"

namespace mvkp {

struct CdikpOptions {
  int dims = 20;        // Walsh–Hadamard kernels kept, DC excluded (SPEC: 8..100; thesis: 20)
  int patch_size = 32;  // side of the canonical patch; a power of two (thesis: 32)
  // Patch side in units of KeyPoint::size (SIFT's own window is 6 x size).
  // Defaults measured with bench/cdikp_tune.cc (mvkp_cdikp_tune, one thread,
  // OpenCV 4.6): Oxford bikes/boat/graf/leuven, img1 -> img2..6 (20 pairs),
  // SIFT keypoints, BFMatcher ratio 0.8, RANSAC 3 px. Homography success
  // (mean corner error < 10 px) is 0.85-0.90 for every patch size in {16, 32}
  // and scale factor in {4, 6, 8, 10, 12} (SIFT-128: 0.90); correct matches
  // per pair rise from 495 at 4 to a plateau over 8-12, highest at 10 (557
  // for patch 32, 553 for 16; SIFT 629). Patch 32 had more correct matches
  // than 16 on 12 of 20 pairs (fewer on 5), at 2.6 against 0.85 us per
  // keypoint (SIFT's compute: 25 us), so the thesis's 32 stays.
  double scale_factor = 10;
  // OpenCV SIFT detector settings (cv::SIFT::create), OpenCV's defaults.
  int nfeatures = 0;  // 0 = keep all
  int n_octave_layers = 3;
  double contrast_threshold = 0.04;
  double edge_threshold = 10;
  double sigma = 1.6;
  void Check() const;  // throws mvkp::Error(kInvalidArgument)
};

class CDIKP : public cv::Feature2D {
 public:
  static cv::Ptr<CDIKP> create(const CdikpOptions& options = {});
  explicit CDIKP(const CdikpOptions& options = {});

  // Input images: 8-bit gray, BGR or BGRA (converted to gray). An empty image
  // throws mvkp::Error(kBadImage); other types throw kBadImage too. An image
  // without keypoints gives no keypoints and an empty descriptor Mat.
  using cv::Feature2D::compute;
  using cv::Feature2D::detect;
  void detect(cv::InputArray image, std::vector<cv::KeyPoint>& keypoints,
              cv::InputArray mask = cv::noArray()) override;
  // Describes the given keypoints (all of them, in order; see Borders above).
  // Keypoint sizes must be > 0 and coordinates finite (else kInvalidArgument).
  void compute(cv::InputArray image, std::vector<cv::KeyPoint>& keypoints,
               cv::OutputArray descriptors) override;
  void detectAndCompute(cv::InputArray image, cv::InputArray mask, std::vector<cv::KeyPoint>& keypoints,
                        cv::OutputArray descriptors, bool useProvidedKeypoints = false) override;

  int descriptorSize() const override { return projector_.dims(); }
  int descriptorType() const override { return CV_32F; }
  int defaultNorm() const override { return cv::NORM_L2; }
  bool empty() const override { return false; }
  cv::String getDefaultName() const override { return "Feature2D.CDIKP"; }

  const CdikpOptions& options() const { return options_; }

 private:
  CdikpOptions options_;
  wht::Projector projector_;
  cv::Ptr<cv::SIFT> sift_;
};

// The canonical patch CDIKP projects for one keypoint: patch_size x
// patch_size, CV_32F, sampled as described above from `gray` (8-bit, one
// channel). For tests and for looking at what the descriptor sees.
cv::Mat CdikpPatch(const cv::Mat& gray, const cv::KeyPoint& keypoint, const CdikpOptions& options = {});

}  // namespace mvkp
