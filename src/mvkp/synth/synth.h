// Synthetic views with known geometry: the affine training views of MVKP
// (thesis §3.2.1) and cluttered test scenes with ground-truth homographies
// (thesis §3.4.3, plus perspective, clutter, lighting, blur and noise).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

// A = R(theta) * R(-phi) * diag(lambda1, lambda2) * R(phi), then translation (t1, t2).
struct AffineParams {
  double theta = 0, phi = 0, lambda1 = 1, lambda2 = 1;
  int t1 = 0, t2 = 0;
};
cv::Matx22d AffineMatrix(const AffineParams& p);

struct ViewSamplerOptions {
  double min_scale = 0.4;   // lambda range (thesis: [0.4, 1.6])
  double max_scale = 1.6;
  int max_translation = 3;  // t1, t2 in {0..3}
  std::uint64_t seed = 42;
};

// n parameter sets covering theta in [-pi, pi], phi in [-pi/2, pi/2] and
// lambda1, lambda2 in [min_scale, max_scale]: a Halton sequence with a seeded
// random shift (Cranley–Patterson), so coverage is even and reproducible.
std::vector<AffineParams> SampleAffineViews(int n, const ViewSamplerOptions& options);

// The van der Corput radical inverse of i in `base` (the Halton sequence's
// coordinates): digits of i mirrored behind the point, in [0, 1).
double RadicalInverse(int base, std::uint64_t i);

// Warps src into a dst of `size` by H (src pixels -> dst pixels). Where H
// shrinks the image, src is low-pass filtered first so the view is not aliased.
// If mask is given, it receives 255 where dst shows src.
void WarpAntiAliased(const cv::Mat& src, const cv::Matx33d& H, cv::Size size, cv::Mat& dst,
                     cv::Mat* mask = nullptr, int border_value = 0);

struct SceneOptions {
  int width = 640, height = 480;  // frame size
  double min_scale = 0.4;         // affine lambda range, as in training
  double max_scale = 1.6;
  double perspective = 0.1;       // max relative depth change across the target (0 = affine only)
  bool clutter = true;            // random shapes and texture behind the target
  bool lighting = true;           // gain in [0.6, 1.4], offset in [-30, 30], linear gradient
  double max_blur = 1.2;          // Gaussian sigma drawn from [0, max_blur]
  double max_noise = 5.0;         // Gaussian noise sigma drawn from [0, max_noise]
  int target_max_side = 320;      // PrepareTarget resizes the target to this longest side (0: keep)
  void Check() const;
};

struct SceneView {
  cv::Mat image;    // same channel count as the target
  cv::Matx33d H;    // maps target pixels to image pixels
};

// Resizes the target so its longest side is max_side (area interpolation); 0 keeps it.
cv::Mat PrepareTarget(const cv::Mat& target, int max_side);

// One scene view of the target, reproducible from the seed. If background is
// non-empty it is used (resized) behind the clutter instead of a flat colour.
SceneView MakeSceneView(const cv::Mat& target, const SceneOptions& options, std::uint64_t seed,
                        const cv::Mat& background = cv::Mat());

}  // namespace mvkp
