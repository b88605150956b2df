#include "mvkp/cdikp/cdikp.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

wht::ProjectorOptions ToProjector(const CdikpOptions& o) {
  o.Check();
  wht::ProjectorOptions p;
  p.patch_size = o.patch_size;
  p.dims = o.dims;
  p.drop_dc = true;
  p.Check();
  return p;
}

// 8-bit gray view or copy of the input; throws on empty or unsupported images.
cv::Mat ToGray(cv::InputArray image) {
  Require(!image.empty(), ErrorCode::kBadImage, "CDIKP: empty image");
  const cv::Mat m = image.getMat();
  Require(m.depth() == CV_8U && (m.channels() == 1 || m.channels() == 3 || m.channels() == 4),
          ErrorCode::kBadImage,
          "CDIKP: image must be 8-bit gray, BGR or BGRA (got " + std::to_string(m.channels()) +
              " channel(s) of depth " + std::to_string(m.depth()) + ")");
  if (m.channels() == 1) return m;
  cv::Mat gray;
  cv::cvtColor(m, gray, m.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
  return gray;
}

void CheckKeypoint(const cv::KeyPoint& kp) {
  Require(std::isfinite(kp.pt.x) && std::isfinite(kp.pt.y) && std::isfinite(kp.size) && std::isfinite(kp.angle) &&
              kp.size > 0.f,
          ErrorCode::kInvalidArgument, "CDIKP: keypoints need finite coordinates and a size > 0");
}

// Gaussian pyramid, CV_32F, level 0 = the image, built on demand up to a level.
class Pyramid {
 public:
  explicit Pyramid(const cv::Mat& gray) { gray.convertTo(levels_.emplace_back(), CV_32F); }
  // The level to sample with spacing s (image pixels between patch pixels):
  // floor(log2 s), so that the spacing there is in [1, 2); 0 when s < 1.
  int LevelFor(double spacing) {
    int want = spacing >= 1.0 ? int(std::floor(std::log2(spacing))) : 0;
    while (int(levels_.size()) <= want) {
      const cv::Mat& last = levels_.back();
      if (std::min(last.rows, last.cols) < 4) break;  // no room for another octave
      cv::Mat next;
      cv::pyrDown(last, next);
      levels_.push_back(std::move(next));
    }
    return std::min(want, int(levels_.size()) - 1);
  }
  const cv::Mat& level(int l) const { return levels_[std::size_t(l)]; }

 private:
  std::vector<cv::Mat> levels_;
};

// Samples the rotated, scaled patch of kp bilinearly (border replicated).
// Calls put(j, i, value) for patch column j and row i.
template <class Put>
void SamplePatch(Pyramid& pyr, const cv::KeyPoint& kp, int k, double scale_factor, Put&& put) {
  const double spacing = scale_factor * kp.size / k;
  const int l = pyr.LevelFor(spacing);
  const cv::Mat& img = pyr.level(l);
  // pyrDown centres level pixel i on pixel 2i of the level below.
  const double f = std::ldexp(1.0, -l);
  const double sp = spacing * f;
  const double a = kp.angle >= 0.f ? kp.angle * (CV_PI / 180.0) : 0.0;
  const float c = float(std::cos(a) * sp), s = float(std::sin(a) * sp);
  const float x0 = float(kp.pt.x * f), y0 = float(kp.pt.y * f);
  const float h = (k - 1) / 2.f;
  const int w = img.cols, ht = img.rows;
  const float* data = img.ptr<float>(0);
  const std::size_t stride = img.step1();
  // Patch corners inside [0, w-1) x [0, ht-1)? Then no clamping is needed.
  const float ex = std::abs(c) * h + std::abs(s) * h, ey = ex;
  const bool inside = x0 - ex >= 0.f && y0 - ey >= 0.f && x0 + ex < float(w - 1) - 0.01f &&
                      y0 + ey < float(ht - 1) - 0.01f;
  for (int i = 0; i < k; ++i) {
    const float v = i - h;
    float x = x0 - c * h - s * v;  // u = -h
    float y = y0 - s * h + c * v;
    if (inside) {
      for (int j = 0; j < k; ++j, x += c, y += s) {
        const int xi = int(x), yi = int(y);
        const float fx = x - xi, fy = y - yi;
        const float* r0 = data + std::size_t(yi) * stride + xi;
        const float* r1 = r0 + stride;
        put(j, i, r0[0] + fx * (r0[1] - r0[0]) + fy * ((r1[0] + fx * (r1[1] - r1[0])) - (r0[0] + fx * (r0[1] - r0[0]))));
      }
    } else {
      for (int j = 0; j < k; ++j, x += c, y += s) {
        const float xc = std::clamp(x, 0.f, float(w - 1)), yc = std::clamp(y, 0.f, float(ht - 1));
        const int xi = std::min(int(xc), w - 1), yi = std::min(int(yc), ht - 1);
        const float fx = xc - xi, fy = yc - yi;
        const int dx = xi + 1 < w ? 1 : 0;
        const std::size_t dy = yi + 1 < ht ? stride : 0;
        const float* r0 = data + std::size_t(yi) * stride + xi;
        const float* r1 = r0 + dy;
        const float top = r0[0] + fx * (r0[dx] - r0[0]);
        const float bot = r1[0] + fx * (r1[dx] - r1[0]);
        put(j, i, top + fy * (bot - top));
      }
    }
  }
}

}  // namespace

void CdikpOptions::Check() const {
  Require(dims >= 1 && dims <= 100, ErrorCode::kInvalidArgument, "CDIKP: dims must be in 1..100");
  Require(patch_size >= 4 && patch_size <= 256 && (patch_size & (patch_size - 1)) == 0,
          ErrorCode::kInvalidArgument, "CDIKP: patch_size must be a power of two in 4..256");
  Require(std::isfinite(scale_factor) && scale_factor > 0 && scale_factor <= 100, ErrorCode::kInvalidArgument,
          "CDIKP: scale_factor must be in (0, 100]");
  Require(nfeatures >= 0, ErrorCode::kInvalidArgument, "CDIKP: nfeatures must be >= 0 (0 = all)");
  Require(n_octave_layers >= 1 && n_octave_layers <= 20, ErrorCode::kInvalidArgument,
          "CDIKP: n_octave_layers must be in 1..20");
  Require(contrast_threshold >= 0, ErrorCode::kInvalidArgument, "CDIKP: contrast_threshold must be >= 0");
  Require(edge_threshold > 0, ErrorCode::kInvalidArgument, "CDIKP: edge_threshold must be > 0");
  Require(sigma > 0 && sigma <= 20, ErrorCode::kInvalidArgument, "CDIKP: sigma must be in (0, 20]");
}

cv::Ptr<CDIKP> CDIKP::create(const CdikpOptions& options) { return cv::makePtr<CDIKP>(options); }

CDIKP::CDIKP(const CdikpOptions& options)
    : options_(options),
      projector_(ToProjector(options)),
      sift_(cv::SIFT::create(options.nfeatures, options.n_octave_layers, options.contrast_threshold,
                             options.edge_threshold, options.sigma)) {}

void CDIKP::detect(cv::InputArray image, std::vector<cv::KeyPoint>& keypoints, cv::InputArray mask) {
  const cv::Mat gray = ToGray(image);
  keypoints.clear();
  if (!mask.empty())
    Require(mask.type() == CV_8UC1 && mask.size() == gray.size(), ErrorCode::kInvalidArgument,
            "CDIKP: mask must be 8-bit, one channel, the size of the image");
  sift_->detect(gray, keypoints, mask);
}

void CDIKP::compute(cv::InputArray image, std::vector<cv::KeyPoint>& keypoints, cv::OutputArray descriptors) {
  const cv::Mat gray = ToGray(image);
  for (const auto& kp : keypoints) CheckKeypoint(kp);
  const int K = projector_.dims();
  if (keypoints.empty()) {
    descriptors.release();
    return;
  }
  descriptors.create(int(keypoints.size()), K, CV_32F);
  cv::Mat out = descriptors.getMat();
  const int k = options_.patch_size, n = projector_.grid(), b = projector_.block();
  int shift = 0;  // log2(b): patch pixel -> grid cell
  while ((1 << shift) < b) ++shift;
  Pyramid pyr(gray);
  std::vector<float> g(std::size_t(n) * n);
  for (std::size_t q = 0; q < keypoints.size(); ++q) {
    std::fill(g.begin(), g.end(), 0.f);
    float* gp = g.data();
    SamplePatch(pyr, keypoints[q], k, options_.scale_factor,
                [gp, n, shift](int j, int i, float v) { gp[(i >> shift) * n + (j >> shift)] += v; });
    float* d = out.ptr<float>(int(q));
    projector_.ProjectGrid(gp, d);
    double ss = 0;
    for (int t = 0; t < K; ++t) ss += double(d[t]) * d[t];
    // L2 normalisation; a flat patch (all kernels ~0) stays all-zero.
    const float inv = ss > 1e-12 ? float(1.0 / std::sqrt(ss)) : 0.f;
    for (int t = 0; t < K; ++t) d[t] *= inv;
  }
}

void CDIKP::detectAndCompute(cv::InputArray image, cv::InputArray mask, std::vector<cv::KeyPoint>& keypoints,
                             cv::OutputArray descriptors, bool useProvidedKeypoints) {
  const cv::Mat gray = ToGray(image);
  if (!useProvidedKeypoints) detect(gray, keypoints, mask);
  compute(gray, keypoints, descriptors);
}

cv::Mat CdikpPatch(const cv::Mat& gray, const cv::KeyPoint& keypoint, const CdikpOptions& options) {
  options.Check();
  const cv::Mat g = ToGray(gray);
  CheckKeypoint(keypoint);
  Pyramid pyr(g);
  cv::Mat patch(options.patch_size, options.patch_size, CV_32F);
  SamplePatch(pyr, keypoint, options.patch_size, options.scale_factor,
              [&patch](int j, int i, float v) { patch.at<float>(i, j) = v; });
  return patch;
}

}  // namespace mvkp
