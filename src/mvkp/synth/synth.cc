#include "mvkp/synth/synth.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
double RadicalInverse(int base, std::uint64_t i) {
  double f = 1.0, r = 0.0;
  while (i > 0) {
    f /= base;
    r += f * double(i % base);
    i /= base;
  }
  return r;
}

namespace {

cv::Matx22d Rot(double a) { return {std::cos(a), -std::sin(a), std::sin(a), std::cos(a)}; }

// Geometric-mean scale of H's Jacobian at point p.
double LocalScale(const cv::Matx33d& H, cv::Point2d p) {
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  const double x = (H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) / w;
  const double y = (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) / w;
  const double j00 = (H(0, 0) - x * H(2, 0)) / w, j01 = (H(0, 1) - x * H(2, 1)) / w;
  const double j10 = (H(1, 0) - y * H(2, 0)) / w, j11 = (H(1, 1) - y * H(2, 1)) / w;
  return std::sqrt(std::abs(j00 * j11 - j01 * j10));
}

}  // namespace

cv::Matx22d AffineMatrix(const AffineParams& p) {
  return Rot(p.theta) * Rot(-p.phi) * cv::Matx22d(p.lambda1, 0, 0, p.lambda2) * Rot(p.phi);
}

std::vector<AffineParams> SampleAffineViews(int n, const ViewSamplerOptions& o) {
  Require(n >= 1, ErrorCode::kInvalidArgument, "number of views must be >= 1");
  Require(o.min_scale > 0 && o.max_scale >= o.min_scale && o.max_scale <= 10, ErrorCode::kInvalidArgument,
          "scale range must satisfy 0 < min <= max <= 10");
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  double shift[4];
  for (double& s : shift) s = u01(rng);
  std::uniform_int_distribution<int> ut(0, std::max(0, o.max_translation));
  std::vector<AffineParams> out(n);
  for (int i = 0; i < n; ++i) {
    const int bases[4] = {2, 3, 5, 7};
    double h[4];
    for (int d = 0; d < 4; ++d) h[d] = std::fmod(RadicalInverse(bases[d], std::uint64_t(i) + 1) + shift[d], 1.0);
    AffineParams& p = out[i];
    p.theta = -CV_PI + 2 * CV_PI * h[0];
    p.phi = -CV_PI / 2 + CV_PI * h[1];
    p.lambda1 = o.min_scale + (o.max_scale - o.min_scale) * h[2];
    p.lambda2 = o.min_scale + (o.max_scale - o.min_scale) * h[3];
    p.t1 = ut(rng);
    p.t2 = ut(rng);
  }
  return out;
}

void WarpAntiAliased(const cv::Mat& src, const cv::Matx33d& H, cv::Size size, cv::Mat& dst, cv::Mat* mask,
                     int border_value) {
  const double s = LocalScale(H, {src.cols / 2.0, src.rows / 2.0});
  // Never `in = src` before blurring into `in`: that would blur the caller's
  // image in place (shared buffer).
  cv::Mat in;
  if (s < 0.95) {
    const double sigma = 0.6 * std::sqrt(1.0 / (s * s) - 1.0);
    cv::GaussianBlur(src, in, cv::Size(), sigma, sigma, cv::BORDER_REFLECT_101);
  } else {
    in = src;
  }
  cv::warpPerspective(in, dst, cv::Mat(H), size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                      cv::Scalar::all(border_value));
  if (mask) {
    cv::Mat ones(src.size(), CV_8UC1, cv::Scalar(255));
    cv::warpPerspective(ones, *mask, cv::Mat(H), size, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  }
}

void SceneOptions::Check() const {
  Require(width >= 32 && height >= 32 && width <= 8192 && height <= 8192, ErrorCode::kInvalidArgument,
          "scene size must be within 32..8192 pixels per side");
  Require(min_scale > 0 && max_scale >= min_scale && max_scale <= 10, ErrorCode::kInvalidArgument,
          "scale range must satisfy 0 < min <= max <= 10");
  Require(perspective >= 0 && perspective < 0.5, ErrorCode::kInvalidArgument, "perspective must be in [0, 0.5)");
  Require(max_blur >= 0 && max_blur <= 10 && max_noise >= 0 && max_noise <= 100, ErrorCode::kInvalidArgument,
          "blur must be in [0, 10] and noise in [0, 100]");
  Require(target_max_side >= 0, ErrorCode::kInvalidArgument, "target size must be >= 0");
}

cv::Mat PrepareTarget(const cv::Mat& target, int max_side) {
  const int side = std::max(target.cols, target.rows);
  if (max_side <= 0 || side == max_side) return target.clone();
  const double f = double(max_side) / side;
  cv::Mat out;
  cv::resize(target, out, cv::Size(std::max(1, int(std::lround(target.cols * f))),
                                   std::max(1, int(std::lround(target.rows * f)))),
             0, 0, f < 1 ? cv::INTER_AREA : cv::INTER_CUBIC);
  return out;
}

SceneView MakeSceneView(const cv::Mat& target, const SceneOptions& o, std::uint64_t seed, const cv::Mat& background) {
  o.Check();
  CV_Assert(!target.empty() && target.depth() == CV_8U);
  std::mt19937_64 rng(seed);
  cv::RNG cvrng(seed ^ 0x9E3779B97F4A7C15ull);  // OpenCV's fills, seeded too
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  const int type = target.type();
  const int ch = target.channels();
  const cv::Size size(o.width, o.height);
  auto Colour = [&] {
    const double g = U(0, 255);
    return ch == 1 ? cv::Scalar(g) : cv::Scalar(U(0, 255), U(0, 255), U(0, 255));
  };

  // Background: a photo or a flat colour, then clutter.
  cv::Mat img(size, type, Colour());
  if (!background.empty()) {
    cv::Mat bg = background;
    if (bg.channels() != ch) cv::cvtColor(background, bg, ch == 1 ? cv::COLOR_BGR2GRAY : cv::COLOR_GRAY2BGR);
    cv::resize(bg, img, size, 0, 0, cv::INTER_AREA);
  }
  if (o.clutter) {
    cv::Mat tex(size / 8, CV_8UC1);
    cvrng.fill(tex, cv::RNG::UNIFORM, 0, 255);
    cv::Mat tex_up;
    cv::resize(tex, tex_up, size, 0, 0, cv::INTER_CUBIC);
    cv::GaussianBlur(tex_up, tex_up, cv::Size(), 2.0);
    if (ch == 3) cv::cvtColor(tex_up, tex_up, cv::COLOR_GRAY2BGR);
    cv::addWeighted(img, 0.7, tex_up, 0.3, 0, img);
    const int shapes = 40 + int(U(0, 40));
    for (int i = 0; i < shapes; ++i) {
      const cv::Point c(int(U(0, o.width)), int(U(0, o.height)));
      const int r = int(U(4, 60));
      switch (int(U(0, 4))) {
        case 0: cv::rectangle(img, c, c + cv::Point(int(U(-60, 60)), int(U(-60, 60))), Colour(), int(U(0, 2)) ? -1 : 2, cv::LINE_AA); break;
        case 1: cv::circle(img, c, r, Colour(), int(U(0, 2)) ? -1 : 2, cv::LINE_AA); break;
        case 2: cv::line(img, c, c + cv::Point(int(U(-120, 120)), int(U(-120, 120))), Colour(), int(U(1, 4)), cv::LINE_AA); break;
        default: cv::ellipse(img, c, cv::Size(r, int(U(4, 40))), U(0, 180), 0, 360, Colour(), -1, cv::LINE_AA);
      }
    }
  }

  // Geometry: affine from the training ranges, mild perspective, placed in the frame.
  ViewSamplerOptions vs;
  vs.min_scale = o.min_scale;
  vs.max_scale = o.max_scale;
  vs.seed = rng();
  const AffineParams ap = SampleAffineViews(1 + int(U(0, 97)), vs).back();
  const cv::Matx22d A = AffineMatrix(ap);
  const double w = target.cols, h = target.rows;
  // Centre the target at the origin, apply A, then a projective term.
  cv::Matx33d C(1, 0, -w / 2, 0, 1, -h / 2, 0, 0, 1);
  cv::Matx33d Aff(A(0, 0), A(0, 1), 0, A(1, 0), A(1, 1), 0, 0, 0, 1);
  const double side = std::max(w, h);
  const double px = U(-o.perspective, o.perspective) * 2 / side, py = U(-o.perspective, o.perspective) * 2 / side;
  cv::Matx33d P(1, 0, 0, 0, 1, 0, px, py, 1);
  cv::Matx33d H = P * Aff * C;
  // Bounding box of the warped corners, then a translation that keeps the
  // target inside the frame when it fits, centred near the middle otherwise.
  std::vector<cv::Point2d> corners = {{0, 0}, {w, 0}, {w, h}, {0, h}}, wc;
  cv::perspectiveTransform(corners, wc, cv::Mat(H));
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (auto& p : wc) {
    x0 = std::min(x0, p.x); y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x); y1 = std::max(y1, p.y);
  }
  auto Place = [&](double lo, double hi, double extent) {
    const double span = hi - lo;
    if (span <= extent) return U(-lo, extent - hi);
    return (extent - span) / 2 - lo + U(-0.1, 0.1) * (span - extent);
  };
  const double tx = Place(x0, x1, o.width), ty = Place(y0, y1, o.height);
  H = cv::Matx33d(1, 0, tx, 0, 1, ty, 0, 0, 1) * H;
  H = H * (1.0 / H(2, 2));

  cv::Mat warped, mask;
  WarpAntiAliased(target, H, size, warped, &mask);
  warped.copyTo(img, mask);

  if (o.lighting) {
    cv::Mat f;
    img.convertTo(f, CV_32F);
    const double gain = U(0.6, 1.4), offset = U(-30, 30);
    const double gx = U(-0.3, 0.3) / o.width, gy = U(-0.3, 0.3) / o.height;
    cv::Mat ramp(size, CV_32F);
    for (int y = 0; y < o.height; ++y) {
      float* r = ramp.ptr<float>(y);
      for (int x = 0; x < o.width; ++x) r[x] = float(gain * (1.0 + gx * (x - o.width / 2.0) + gy * (y - o.height / 2.0)));
    }
    if (ch == 3) cv::cvtColor(ramp, ramp, cv::COLOR_GRAY2BGR);
    cv::multiply(f, ramp, f);
    f += cv::Scalar::all(offset);
    f.convertTo(img, type);
  }
  const double blur = U(0, o.max_blur);
  if (blur > 0.2) cv::GaussianBlur(img, img, cv::Size(), blur);
  const double noise = U(0, o.max_noise);
  if (noise > 0) {
    cv::Mat n(size, CV_MAKETYPE(CV_32F, ch)), f;
    cvrng.fill(n, cv::RNG::NORMAL, 0, noise);
    img.convertTo(f, CV_32F);
    f += n;
    f.convertTo(img, type);
  }
  return {img, H};
}

}  // namespace mvkp
