#include "mvkp/shapes/shape_context.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/shapes/internal/shift_kernels.h"

namespace mvkp {

void ShapeContextOptions::Check() const {
  Require(points >= 8 && points <= 1024, ErrorCode::kInvalidArgument,
          "ShapeContextOptions.points must be in [8, 1024]");
  Require(radial_bins >= 1 && radial_bins <= 32 && angular_bins >= 1 && angular_bins <= 64,
          ErrorCode::kInvalidArgument, "ShapeContextOptions: radial_bins in [1, 32], angular_bins in [1, 64]");
  Require(r_inner > 0 && r_outer > r_inner, ErrorCode::kInvalidArgument,
          "ShapeContextOptions: need 0 < r_inner < r_outer");
  Require(tangent_span >= 1 && 2 * tangent_span < points, ErrorCode::kInvalidArgument,
          "ShapeContextOptions.tangent_span must be >= 1 and < points / 2");
}

double SignedArea(const Contour& c) {
  double a = 0;
  for (size_t i = 0, n = c.size(); i < n; ++i) {
    const cv::Point2f& p = c[i];
    const cv::Point2f& q = c[(i + 1) % n];
    a += double(p.x) * q.y - double(q.x) * p.y;
  }
  return 0.5 * a;
}

Contour ResampleContour(const Contour& contour, int n) {
  if (contour.size() < 3 || n < 3) return {};
  Contour c = contour;
  if (SignedArea(c) < 0) std::reverse(c.begin(), c.end());
  const size_t m = c.size();
  std::vector<double> cum(m + 1, 0.0);
  for (size_t i = 0; i < m; ++i) cum[i + 1] = cum[i] + cv::norm(c[(i + 1) % m] - c[i]);
  const double len = cum[m];
  if (!(len > 1e-9)) return {};
  Contour out(n);
  size_t seg = 0;
  for (int k = 0; k < n; ++k) {
    const double s = len * k / n;
    while (seg + 1 < m && cum[seg + 1] <= s) ++seg;
    const double sl = cum[seg + 1] - cum[seg];
    const double t = sl > 0 ? (s - cum[seg]) / sl : 0.0;
    const cv::Point2f& p = c[seg];
    const cv::Point2f& q = c[(seg + 1) % m];
    out[k] = cv::Point2f(float(p.x + t * (q.x - p.x)), float(p.y + t * (q.y - p.y)));
  }
  // Start at the smallest y (then smallest x) — the thesis's convention; the
  // matching is shift-invariant anyway.
  int start = 0;
  for (int k = 1; k < n; ++k)
    if (out[k].y < out[start].y || (out[k].y == out[start].y && out[k].x < out[start].x)) start = k;
  std::rotate(out.begin(), out.begin() + start, out.end());
  return out;
}

ShapeDescriptor DescribeAnchors(const Contour& anchors, const std::vector<double>& tangents, const Contour& samples,
                                const std::vector<float>& weights, double scale, const ShapeContextOptions& opt) {
  ShapeDescriptor d;
  const int n = int(anchors.size());
  CV_Assert(tangents.size() == anchors.size() && weights.size() == samples.size());
  if (n == 0 || samples.empty() || !(scale > 1e-6)) return d;
  const int R = opt.radial_bins, A = opt.angular_bins, B = R * A;
  const double log_in = std::log(opt.r_inner), log_out = std::log(opt.r_outer);
  const double r_step = R > 1 ? (log_out - log_in) / (R - 1) : 1.0;
  d.hist = cv::Mat::zeros(n, B, CV_32F);
  const double two_pi = 2 * CV_PI;
  for (int j = 0; j < n; ++j) {
    float* h = d.hist.ptr<float>(j);
    double total = 0;
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const double dx = samples[k].x - anchors[j].x, dy = samples[k].y - anchors[j].y;
      if (dx == 0 && dy == 0) continue;  // the anchor itself
      const double r = std::hypot(dx, dy) / scale, w = weights[k];
      total += w;
      // soft (bilinear) binning in log-radius and angle: robust to the
      // resampling phase and to contour noise
      double rf = 0;
      if (R > 1) rf = std::clamp((std::log(r) - log_in) / r_step, 0.0, double(R - 1));
      const int r0 = std::min(int(rf), R - 1), r1 = std::min(r0 + 1, R - 1);
      const double wr1 = rf - r0, wr0 = 1 - wr1;
      double a = std::atan2(dy, dx) - tangents[j];
      a = std::fmod(a, two_pi);
      if (a < 0) a += two_pi;
      double af = a / two_pi * A - 0.5;
      if (af < 0) af += A;
      int a0 = int(af);
      if (a0 >= A) a0 = A - 1;
      const int a1 = (a0 + 1) % A;
      const double wa1 = af - a0, wa0 = 1 - wa1;
      h[r0 * A + a0] += float(w * wr0 * wa0);
      h[r0 * A + a1] += float(w * wr0 * wa1);
      h[r1 * A + a0] += float(w * wr1 * wa0);
      h[r1 * A + a1] += float(w * wr1 * wa1);
    }
    if (total > 0)
      for (int b = 0; b < B; ++b) h[b] = std::sqrt(h[b] / float(total));
  }
  d.hist_t = d.hist.t();
  d.points = anchors;
  d.scale = scale;
  return d;
}

ShapeDescriptor DescribeContour(const Contour& contour, const ShapeContextOptions& opt) {
  const int n = opt.points;
  Contour p = ResampleContour(contour, n);
  if (p.empty()) return {};
  const cv::RotatedRect box = cv::minAreaRect(p);
  const double diag = std::hypot(box.size.width, box.size.height);
  if (!(diag > 1e-6)) return {};
  std::vector<double> tangent(n);
  for (int j = 0; j < n; ++j) {
    const cv::Point2f t = p[(j + opt.tangent_span) % n] - p[(j - opt.tangent_span + n) % n];
    tangent[j] = std::atan2(t.y, t.x);
  }
  ShapeDescriptor d = DescribeAnchors(p, tangent, p, std::vector<float>(p.size(), 1.0f), diag, opt);
  d.area = std::abs(SignedArea(d.points));
  return d;
}

namespace {
std::vector<cv::Point2f> Polygon(const Contour& contour) {
  std::vector<cv::Point2f> poly;
  if (contour.size() < 3) return poly;
  const double per = cv::arcLength(contour, true);
  cv::approxPolyDP(contour, poly, std::max(1.5, 0.02 * per), true);
  return poly;
}
}  // namespace

int CountCorners(const Contour& contour) { return int(Polygon(contour).size()); }

std::vector<ShapeDescriptor> DescribePartials(const Contour& contour, const ShapeContextOptions& opt,
                                              int min_corners, int max_partials) {
  std::vector<ShapeDescriptor> out;
  std::vector<cv::Point2f> poly = Polygon(contour);
  const int m = int(poly.size());
  if (m < std::max(min_corners, 4) || max_partials <= 0) return out;
  const int len = (m + 1) / 2 + 1;  // corners per partial contour
  const int count = std::min(m, max_partials);
  for (int i = 0; i < count; ++i) {
    const int start = int(std::lround(double(i) * m / count)) % m;
    Contour part;
    for (int k = 0; k < len; ++k) part.push_back(poly[(start + k) % m]);
    ShapeDescriptor d = DescribeContour(part, opt);
    if (d.empty() || d.area < 1e-3 * std::abs(SignedArea(poly))) continue;
    d.partial = true;
    out.push_back(std::move(d));
  }
  return out;
}

std::vector<double> ShiftCosts(const ShapeDescriptor& a, const ShapeDescriptor& b) {
  const int n = a.hist.rows, B = a.hist.cols;
  CV_Assert(n > 0 && b.hist.rows == n && b.hist.cols == B);
  cv::Mat bt_local;
  const cv::Mat& bt = b.hist_t.rows == B && b.hist_t.cols == n ? b.hist_t : (bt_local = b.hist.t());
  CV_Assert(a.hist.type() == CV_32F && bt.type() == CV_32F);
  const size_t len = static_cast<size_t>(n);
  std::vector<float> row(len);
  std::vector<double> cost(len, 0.0);
  internal::BestShiftSums()(a.hist.ptr<float>(0), int(a.hist.step1()), bt.ptr<float>(0), int(bt.step1()), n, B,
                           cost.data(), row.data());
  for (double& c : cost) c = std::clamp(1.0 - c / n, 0.0, 1.0);
  return cost;
}

ShiftCost MatchDescriptors(const ShapeDescriptor& a, const ShapeDescriptor& b) {
  const std::vector<double> c = ShiftCosts(a, b);
  const auto it = std::min_element(c.begin(), c.end());
  return {*it, int(it - c.begin())};
}

std::vector<ShiftCost> BestShifts(const std::vector<double>& costs, int k, double slack) {
  const int n = int(costs.size());
  std::vector<ShiftCost> minima;
  if (n == 0 || k <= 0) return minima;
  const double best = *std::min_element(costs.begin(), costs.end());
  for (int i = 0; i < n; ++i) {
    const double c = costs[i];
    if (c > best * (1 + slack) + 0.02) continue;
    if (c <= costs[(i + 1) % n] && c < costs[(i - 1 + n) % n]) minima.push_back({c, i});
  }
  if (minima.empty()) {
    const auto it = std::min_element(costs.begin(), costs.end());
    minima.push_back({*it, int(it - costs.begin())});
  }
  std::sort(minima.begin(), minima.end(), [](const ShiftCost& x, const ShiftCost& y) {
    return x.cost < y.cost || (x.cost == y.cost && x.shift < y.shift);
  });
  if (int(minima.size()) > k) minima.resize(k);
  return minima;
}

}  // namespace mvkp
