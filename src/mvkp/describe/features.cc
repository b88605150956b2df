#include "mvkp/describe/features.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/internal/orient_kernels.h"

namespace mvkp {
namespace {

wht::ProjectorOptions ToProjector(const DescriberOptions& o) {
  o.Check();
  wht::ProjectorOptions p;
  p.patch_size = o.patch_size;
  p.dims = o.dims;
  p.drop_dc = true;
  return p;
}

inline float Bilinear(const cv::Mat& img, float x, float y) {
  x = std::clamp(x, 0.f, float(img.cols - 1) - 1e-3f);
  y = std::clamp(y, 0.f, float(img.rows - 1) - 1e-3f);
  const int x0 = int(x), y0 = int(y);
  const float fx = x - x0, fy = y - y0;
  const float* r0 = img.ptr<float>(y0) + x0;
  const float* r1 = img.ptr<float>(std::min(y0 + 1, img.rows - 1)) + x0;
  const int dx = x0 + 1 < img.cols ? 1 : 0;
  return (1 - fy) * ((1 - fx) * r0[0] + fx * r0[dx]) + fy * ((1 - fx) * r1[0] + fx * r1[dx]);
}

// Bilinear without the border clamps, for 0 <= x < cols - 2, 0 <= y < rows - 2
// (where the clamps above change nothing: the same value, bit for bit).
inline float BilinearInside(const cv::Mat& img, float x, float y) {
  const int x0 = int(x), y0 = int(y);
  const float fx = x - x0, fy = y - y0;
  const float* r0 = img.ptr<float>(y0) + x0;
  const float* r1 = img.ptr<float>(y0 + 1) + x0;
  return (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
}

}  // namespace

void DescriberOptions::Check() const {
  Require(orientation_radius >= 2 && orientation_radius <= 64, ErrorCode::kInvalidArgument,
          "describer: orientation radius must be in 2..64");
}

void FeatureOptions::Check() const {
  Require(smooth_sigma >= 0.f && smooth_sigma <= 10.f, ErrorCode::kInvalidArgument,
          "smoothing sigma must be in [0, 10]");
  detector.Check();
  describer.Check();
}

Describer::Describer(const DescriberOptions& options)
    : options_(options),
      projector_(ToProjector(options)),
      disc_(std::make_shared<const internal::DiscTable>(options.orientation_radius)) {}

cv::Mat Describer::Prepare(const cv::Mat& smoothed) const {
  CV_Assert(smoothed.type() == CV_8UC1);
  // Block means, one per pixel: box filter of side b. A box at integer X has its
  // centre at X - b/2 + (b-1)/2, hence the half-pixel shift in Compute for even b.
  const int b = projector_.block();
  cv::Mat box;
  cv::boxFilter(smoothed, box, CV_32F, cv::Size(b, b), cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  return box;
}

void Describer::Compute(const cv::Mat& smoothed, std::vector<Keypoint>& kps, float* out) const {
  if (kps.empty()) return;
  Compute(smoothed, Prepare(smoothed), kps, out);
}

void Describer::Compute(const cv::Mat& smoothed, const cv::Mat& box, std::vector<Keypoint>& kps, float* out) const {
  CV_Assert(smoothed.type() == CV_8UC1);
  CV_Assert(box.type() == CV_32F && box.size() == smoothed.size());
  if (kps.empty()) return;
  const int k = options_.patch_size, n = projector_.grid(), b = projector_.block();
  const int K = projector_.dims();
  const float shift = float(b / 2) - float(b - 1) / 2.f;
  std::vector<float> offs(n);
  for (int j = 0; j < n; ++j) offs[j] = -k / 2.f + j * b + b / 2.f;
  // Farthest a rotated sample lies from the centre, with a pixel's margin.
  float reach = 0.f;
  for (const float o : offs) reach = std::max(reach, std::abs(o));
  reach = reach * std::sqrt(2.f) + 1.f;

  const int r = options_.orientation_radius;
  static const internal::DiscMomentsFn simd_moments = internal::DiscMomentsSimd();
  const internal::DiscMomentsFn simd = r <= internal::kMaxSimdRadius ? simd_moments : nullptr;
  std::vector<float> g(std::size_t(n) * n);
  // Gathers index the box image with 32-bit offsets.
  static const internal::BilinearRow8Fn best_row8 = internal::BestBilinearRow8();
  const internal::BilinearRow8Fn row8 = box.total() < (std::size_t(1) << 30) ? best_row8 : nullptr;
  const std::ptrdiff_t stride = std::ptrdiff_t(box.step1());
  for (std::size_t i = 0; i < kps.size(); ++i) {
    Keypoint& kp = kps[i];
    float c = 1.f, s = 0.f;
    if (options_.orient) {
      const int px = int(std::lround(kp.x)), py = int(std::lround(kp.y));
      std::int64_t m10 = 0, m01 = 0;
      const internal::DiscTable& disc = *disc_;
      const std::ptrdiff_t step = std::ptrdiff_t(smoothed.step[0]);
      if (px - r >= 0 && py - r >= 0 && px + r < smoothed.cols && py + r < smoothed.rows) {
        const std::uint8_t* centre = smoothed.ptr<std::uint8_t>(py) + px;
        if (simd && px - 15 >= 0 && px + 16 < smoothed.cols)
          simd(centre, step, disc, m10, m01);
        else
          internal::DiscMomentsScalar(centre, step, disc, m10, m01);
      } else {  // near the border: clamp reads
        for (int v = -r; v <= r; ++v) {
          const int yy = std::clamp(py + v, 0, smoothed.rows - 1);
          const std::uint8_t* row = smoothed.ptr<std::uint8_t>(yy);
          const int w = disc.umax[std::abs(v)];
          for (int u = -w; u <= w; ++u) {
            const int val = row[std::clamp(px + u, 0, smoothed.cols - 1)];
            m10 += std::int64_t(u) * val;
            m01 += std::int64_t(v) * val;
          }
        }
      }
      kp.angle = float(std::atan2(double(m01), double(m10)));
      c = std::cos(kp.angle);
      s = std::sin(kp.angle);
    } else {
      kp.angle = 0.f;
    }
    // Sample the block means at the rotated block centres.
    const float cx = kp.x - 0.5f + shift, cy = kp.y - 0.5f + shift;
    double sum = 0, sum2 = 0;
    // Away from the border (every rotated sample at least a pixel inside) the
    // clamps are skipped.
    const bool inside = cx - reach >= 0.f && cy - reach >= 0.f && cx + reach < float(box.cols - 2) &&
                        cy + reach < float(box.rows - 2);
    if (inside && n == 8 && row8) {
      // Eight samples at a time (the same values, see BilinearRow8Avx2).
      for (int yi = 0; yi < n; ++yi) row8(box.ptr<float>(), stride, cx, cy, c, s, offs.data(), offs[yi], &g[std::size_t(yi) * 8]);
      for (const float v : g) {
        sum += v;
        sum2 += double(v) * v;
      }
    } else {
      for (int yi = 0; yi < n; ++yi) {
        const float oy = offs[yi];
        for (int xi = 0; xi < n; ++xi) {
          const float ox = offs[xi];
          const float x = cx + c * ox - s * oy, y = cy + s * ox + c * oy;
          const float v = inside ? BilinearInside(box, x, y) : Bilinear(box, x, y);
          g[std::size_t(yi) * n + xi] = v;
          sum += v;
          sum2 += double(v) * v;
        }
      }
    }
    const double nn = double(n) * n;
    const double mean = sum / nn;
    const double var = std::max(0.0, sum2 / nn - mean * mean);
    const float scale = float(1.0 / (std::max(std::sqrt(var), 0.5) * n));
    float* d = out + i * std::size_t(K);
    projector_.ProjectGrid(g.data(), d);
    for (int q = 0; q < K; ++q) d[q] *= scale;
  }
}

cv::Mat ScaleFrameDown(const cv::Mat& gray, double f) {
  if (!(f < 1.0)) return gray;
  cv::Mat img;
  cv::resize(gray, img, cv::Size(std::max(1, int(std::lround(gray.cols * f))), std::max(1, int(std::lround(gray.rows * f)))),
             0, 0, cv::INTER_AREA);
  return img;
}

DetectedFrame DetectFeatures(const cv::Mat& gray, const FeatureOptions& options, const cv::Mat& mask) {
  CV_Assert(gray.type() == CV_8UC1);
  DetectedFrame d;
  Timer t;
  if (options.smooth_sigma > 0.f)
    cv::GaussianBlur(gray, d.smoothed, cv::Size(), options.smooth_sigma, options.smooth_sigma, cv::BORDER_REFLECT_101);
  else
    d.smoothed = gray;
  d.smooth_ms = t.ElapsedMs();
  t.Restart();
  d.keypoints = DetectMinEigen(d.smoothed, options.detector, mask);
  d.detect_ms = t.ElapsedMs();
  return d;
}

Features ExtractFeatures(const cv::Mat& gray, const FeatureOptions& options, const cv::Mat& mask) {
  DetectedFrame d = DetectFeatures(gray, options, mask);
  Features f;
  f.keypoints = std::move(d.keypoints);
  f.smooth_ms = d.smooth_ms;
  f.detect_ms = d.detect_ms;
  Timer t;
  Describer describer(options.describer);
  f.descriptors.create(int(f.keypoints.size()), describer.dims(), CV_32F);
  if (!f.keypoints.empty()) describer.Compute(d.smoothed, f.keypoints, f.descriptors.ptr<float>());
  f.describe_ms = t.ElapsedMs();
  return f;
}

}  // namespace mvkp
