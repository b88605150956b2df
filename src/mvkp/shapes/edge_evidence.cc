#include "mvkp/shapes/edge_evidence.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/shapes/internal/edge_kernels.h"

namespace mvkp {

void EdgeEvidenceOptions::Check() const {
  auto need = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, m); };
  need(step_px > 0 && search_px >= 0 && offset_px > search_px,
       "EdgeEvidenceOptions: need step_px > 0, search_px >= 0, offset_px > search_px");
  need(blur_sigma >= 0 && blur_sigma <= 10, "EdgeEvidenceOptions.blur_sigma in [0, 10]");
  need(min_points >= 1, "EdgeEvidenceOptions.min_points must be >= 1");
  need(min_contrast > 0, "EdgeEvidenceOptions.min_contrast must be > 0");
  need(min_perspective_gain >= 0, "EdgeEvidenceOptions.min_perspective_gain must be >= 0");
  need(outward_growth > 1, "EdgeEvidenceOptions.outward_growth must be > 1");
  need(min_region_points >= 1 && min_region_contrast > 0 && min_regions_on_edges >= 0 && min_regions_on_edges <= 1,
       "EdgeEvidenceOptions: min_region_points >= 1, min_region_contrast > 0, min_regions_on_edges in [0, 1]");
  need(max_lean_px_per_m >= 0 && max_lean_px_per_m <= 10 && min_lean_gain >= 0 && min_lean_outlines >= 3 &&
           min_lean_height_spread_m >= 0,
       "EdgeEvidenceOptions: max_lean_px_per_m in [0, 10], min_lean_gain >= 0, min_lean_outlines >= 3, "
       "min_lean_height_spread_m >= 0");
  need(roof_shrink_px >= 0 && roof_shrink_px <= 10 && roof_ring_px >= 1 && roof_ring_px <= 20 && min_roof_regions >= 1 &&
           min_roof_veto_regions >= 1,
       "EdgeEvidenceOptions: roof_shrink_px in [0, 10], roof_ring_px in [1, 20], min_roof_regions >= 1, "
       "min_roof_veto_regions >= 1");
  need(roof_accept >= 0 && roof_veto >= 0 && roof_veto_below >= 0 && min_contrast_with_roofs > 0,
       "EdgeEvidenceOptions: roof_accept, roof_veto, roof_veto_below >= 0, min_contrast_with_roofs > 0");
  need(relocate_radius_px > 0 && relocate_radius_px <= 200 && relocate_grid_px > 0 &&
           relocate_grid_px <= relocate_radius_px && relocate_cells >= 2 && relocate_cells <= 16 &&
           relocate_min_gain >= 0 && relocate_rounds >= 0 && relocate_lean_gain >= 0 && relocate_lean_roof_gain >= 0 &&
           relocate_lean_min_gain >= 0 &&
           (relocate_lean_gain == 0 || relocate_lean_min_gain <= relocate_lean_gain) && relocate_lean_outlines >= 1,
       "EdgeEvidenceOptions: relocate_radius_px in (0, 200], relocate_grid_px in (0, relocate_radius_px], "
       "relocate_cells in [2, 16], relocate_min_gain >= 0, relocate_rounds >= 0, relocate_lean_gain >= 0, "
       "relocate_lean_roof_gain >= 0, relocate_lean_min_gain in [0, relocate_lean_gain] (unless that is 0: off), "
       "relocate_lean_outlines >= 1");
}

namespace {

inline cv::Point2d Map(const cv::Matx33d& H, cv::Point2d p) {
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  const double iw = std::abs(w) > 1e-12 ? 1.0 / w : 1e12;
  return {(H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) * iw, (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) * iw};
}

// sRGB grey level (0-1) -> linear light, and the CIE Lab curve f(t).
inline double SrgbToLinear(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }
inline double LabCurve(double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; }

}  // namespace

cv::Mat EdgeEvidence::Chroma(const cv::Mat& bgr) {
  Require(!bgr.empty() && bgr.type() == CV_8UC3, ErrorCode::kInvalidArgument, "EdgeEvidence::Chroma: need 8-bit BGR");
  // sRGB -> linear, and the CIE Lab curve f(t), as tables (OpenCV's 8-bit Lab
  // conversion builds tables of several MB on first use)
  constexpr int kCurve = 4096;
  static const auto tables = [] {
    std::pair<std::array<float, 256>, std::array<float, kCurve + 1>> t;
    for (int i = 0; i < 256; ++i) t.first[size_t(i)] = float(SrgbToLinear(i / 255.0));
    for (int i = 0; i <= kCurve; ++i) t.second[size_t(i)] = float(LabCurve(double(i) / kCurve));
    return t;
  }();
  const auto& lin = tables.first;
  const auto& curve = tables.second;
  auto f = [&](float x) { return curve[size_t(std::clamp(int(x * kCurve + 0.5f), 0, kCurve))]; };
  cv::Mat half;
  cv::resize(bgr, half, cv::Size((bgr.cols + 1) / 2, (bgr.rows + 1) / 2), 0, 0, cv::INTER_AREA);
  cv::Mat ab(half.size(), CV_8UC2);
  for (int y = 0; y < half.rows; ++y) {
    const uchar* p = half.ptr<uchar>(y);
    uchar* q = ab.ptr<uchar>(y);
    for (int x = 0; x < half.cols; ++x, p += 3, q += 2) {
      const float B = lin[p[0]], G = lin[p[1]], R = lin[p[2]];
      const float X = (0.412453f * R + 0.357580f * G + 0.180423f * B) / 0.950456f;
      const float Y = 0.212671f * R + 0.715160f * G + 0.072169f * B;
      const float Z = (0.019334f * R + 0.119193f * G + 0.950227f * B) / 1.088754f;
      const float fy = f(Y);
      q[0] = cv::saturate_cast<uchar>(500.f * (f(X) - fy) + 128.f);
      q[1] = cv::saturate_cast<uchar>(200.f * (fy - f(Z)) + 128.f);
    }
  }
  return ab;
}

EdgeEvidence::EdgeEvidence(const cv::Mat& photo, double photo_scale, const std::vector<Contour>& depth_regions,
                           const EdgeEvidenceOptions& options, const std::vector<float>& heights,
                           const cv::Mat& chroma)
    : opt_(options), photo_scale_(photo_scale) {
  opt_.Check();
  Require(!photo.empty() && photo.depth() == CV_8U && (photo.channels() == 1 || photo.channels() == 3),
          ErrorCode::kInvalidArgument, "EdgeEvidence: the photo must be 8-bit grey or BGR");
  Require(photo_scale > 0 && std::isfinite(photo_scale), ErrorCode::kInvalidArgument,
          "EdgeEvidence: photo_scale must be > 0");
  Require(heights.empty() || heights.size() == depth_regions.size(), ErrorCode::kInvalidArgument,
          "EdgeEvidence: heights must be empty or one per depth region");
  cv::Mat g;
  if (photo.channels() == 3) cv::cvtColor(photo, g, cv::COLOR_BGR2GRAY);
  else g = photo;
  g.convertTo(grey_, CV_32F);
  if (opt_.blur_sigma > 0) cv::GaussianBlur(grey_, grey_, cv::Size(), opt_.blur_sigma);
  grey8_ = g;
  if (photo.channels() == 3) chroma_ = Chroma(photo);
  else if (!chroma.empty()) {
    Require(chroma.type() == CV_8UC2 && chroma.cols == (photo.cols + 1) / 2 && chroma.rows == (photo.rows + 1) / 2,
            ErrorCode::kInvalidArgument, "EdgeEvidence: chroma must be the photo's Chroma()");
    chroma_ = chroma;
  }
  outlines_ = depth_regions;
  outline_h_.assign(depth_regions.size(), 0.f);
  for (size_t ci = 0; ci < heights.size(); ++ci)
    outline_h_[ci] = std::isfinite(heights[ci]) ? std::max(0.f, heights[ci]) : 0.f;

  // Outline samples every step_px of arc length, with normals from the
  // neighbouring samples (closed contours).
  for (size_t ci = 0; ci < depth_regions.size(); ++ci) {
    const Contour& c = depth_regions[ci];
    if (c.size() < 3) continue;
    const float hc = heights.empty() || !std::isfinite(heights[ci]) ? 0.f : std::max(0.f, heights[ci]);
    std::vector<cv::Point2f> pts;
    double carry = 0;
    for (size_t i = 0, n = c.size(); i < n; ++i) {
      const cv::Point2f a = c[i], b = c[(i + 1) % n];
      const double len = cv::norm(b - a);
      double t = carry;
      for (; t < len; t += opt_.step_px) pts.push_back(a + (b - a) * float(t / len));
      carry = t - len;
    }
    const size_t n = pts.size();
    if (n < 6) continue;
    for (size_t i = 0; i < n; ++i) {
      const cv::Point2f d = pts[(i + 1) % n] - pts[(i + n - 1) % n];
      const double len = cv::norm(d);
      if (len < 1e-6) continue;
      samples_.push_back({pts[i], cv::Point2f(float(-d.y / len), float(d.x / len)), regions_, hc});
    }
    ++regions_;
  }
  // bound the cost on very large scenes: keep an even subset
  constexpr size_t kMaxSamples = 6000;
  if (samples_.size() > kMaxSamples) {
    std::vector<Sample> kept;
    kept.reserve(kMaxSamples);
    for (size_t i = 0; i < kMaxSamples; ++i) kept.push_back(samples_[i * samples_.size() / kMaxSamples]);
    samples_.swap(kept);
  }
  for (const Sample& s : samples_) {
    col_qx_.push_back(s.q.x), col_qy_.push_back(s.q.y), col_nx_.push_back(s.n.x), col_ny_.push_back(s.n.y);
    col_h_.push_back(s.h);
  }
  if (!heights.empty() && !samples_.empty()) {
    std::vector<float> hs;
    for (const Sample& s : samples_) hs.push_back(s.h);
    std::nth_element(hs.begin(), hs.begin() + hs.size() / 2, hs.end());
    ref_height_ = hs[hs.size() / 2];
    has_heights_ = ref_height_ > 1.0;  // a lean needs buildings of some height
  }
}

double EdgeEvidence::OnEdge(const cv::Matx33d& D, cv::Point2d lean, double offset_px, double search_px, int* points,
                            const cv::Rect2d* support, std::vector<double>* region_sum,
                            std::vector<int>* region_count, int stride) const {
  internal::EdgeTapArgs a;
  a.image = grey_.ptr<float>(0);
  a.step = std::ptrdiff_t(grey_.step1());
  a.width = float(grey_.cols), a.height = float(grey_.rows);
  for (int i = 0; i < 9; ++i) a.D[i] = D.val[i];
  a.lean_x = lean.x, a.lean_y = lean.y;
  a.offset_px = offset_px, a.search_px = search_px;
  // a point is scored when the whole reference window (+-offset) fits, so
  // on and off are averaged over the same outline points
  a.reach_px = opt_.offset_px + opt_.search_px, a.fit_search_px = opt_.search_px;
  const internal::EdgeTapsFn taps = internal::BestEdgeTaps(a);
  double sum = 0;
  int count = 0;
  constexpr int kBlock = 128;
  float best[kBlock];
  std::uint8_t valid[kBlock];
  // sums in sample order; sample i of the block is index[i] (or first + i)
  auto add = [&](int n, const int* index, size_t first) {
    for (int i = 0; i < n; ++i) {
      if (!valid[i]) continue;
      sum += best[i];
      ++count;
      if (region_sum) {
        const size_t r = size_t(samples_[index ? size_t(index[i]) : first + size_t(i)].region);
        (*region_sum)[r] += best[i], ++(*region_count)[r];
      }
    }
  };
  if (stride == 1 && !support) {  // every sample: the columns as they are
    for (size_t s0 = 0; s0 < samples_.size(); s0 += kBlock) {
      const int n = int(std::min<size_t>(kBlock, samples_.size() - s0));
      taps(a, &col_qx_[s0], &col_qy_[s0], &col_nx_[s0], &col_ny_[s0], &col_h_[s0], n, best, valid);
      add(n, nullptr, s0);
    }
  } else {  // every stride-th sample in the support, packed
    float qx[kBlock], qy[kBlock], nx[kBlock], ny[kBlock], hs[kBlock];
    int index[kBlock];
    for (size_t si = 0; si < samples_.size();) {
      int n = 0;
      for (; n < kBlock && si < samples_.size(); si += size_t(stride)) {
        const Sample& s = samples_[si];
        if (support && !support->contains(cv::Point2d(s.q))) continue;
        qx[n] = s.q.x, qy[n] = s.q.y, nx[n] = s.n.x, ny[n] = s.n.y, hs[n] = s.h, index[n] = int(si);
        ++n;
      }
      if (n == 0) break;
      taps(a, qx, qy, nx, ny, hs, n, best, valid);
      add(n, index, 0);
    }
  }
  *points = count;
  return count ? sum / count : 0.0;
}

bool EdgeEvidence::Accepts(const EdgeScore& s) const {
  if (!s.enough) return false;
  const bool roofs = s.roof_regions >= opt_.min_roof_regions;
  if (s.roof_regions >= opt_.min_roof_veto_regions && opt_.roof_veto > 0 && s.roof_contrast < opt_.roof_veto &&
      s.contrast < opt_.roof_veto_below)
    return false;
  if (s.contrast >= opt_.min_contrast) return true;
  return roofs && opt_.roof_accept > 0 && s.roof_contrast >= opt_.roof_accept &&
         s.contrast >= opt_.min_contrast_with_roofs;
}

void EdgeEvidence::ScoreRoofs(const cv::Matx33d& photo_to_depth, cv::Point2d lean, EdgeScore* s) const {
  s->roof_regions = 0;
  s->roof_contrast = 0;
  const cv::Matx33d S(photo_scale_, 0, 0, 0, photo_scale_, 0, 0, 0, 1);
  const cv::Matx33d D = S * photo_to_depth.inv();
  const int W = grey8_.cols, H = grey8_.rows;
  const int ring = int(std::lround(opt_.roof_ring_px)), shrink = int(std::lround(opt_.roof_shrink_px));
  const int margin = ring + 3;
  // every outline in the photo (rounded to px, as drawn), and the mask of them all
  std::vector<std::vector<cv::Point>> polys(outlines_.size());
  std::vector<cv::Rect> boxes(outlines_.size());
  std::vector<char> inside(outlines_.size(), 0);
  cv::Mat1b all(H, W, uchar(0));
  const cv::Rect frame(0, 0, W, H);
  for (size_t r = 0; r < outlines_.size(); ++r) {
    bool ok = outlines_[r].size() >= 3;
    for (const cv::Point2f& q : outlines_[r]) {
      if (!ok) break;
      const cv::Point2d p = Map(D, cv::Point2d(q) + lean * double(outline_h_[r]));
      ok = std::isfinite(p.x) && std::isfinite(p.y) && std::abs(p.x) < 1e6 && std::abs(p.y) < 1e6;
      if (ok) polys[r].emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
    }
    if (!ok) { polys[r].clear(); continue; }
    boxes[r] = cv::boundingRect(polys[r]);
    if ((boxes[r] & frame).area() == 0) continue;
    cv::fillPoly(all, std::vector<std::vector<cv::Point>>{polys[r]}, cv::Scalar(255));
    inside[r] = boxes[r].x >= margin && boxes[r].y >= margin && boxes[r].br().x <= W - margin &&
                boxes[r].br().y <= H - margin;
  }
  const cv::Mat k_in = cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * shrink + 1, 2 * shrink + 1});
  const cv::Mat k_ring = cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * (ring + 1) + 1, 2 * (ring + 1) + 1});
  const cv::Mat k_gap = cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3});
  // L* of an sRGB grey level, on OpenCV's 8-bit Lab scale (0-255)
  static const std::array<float, 256> kLightness = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i)
      t[size_t(i)] = float((116.0 * LabCurve(SrgbToLinear(i / 255.0)) - 16.0) * 255.0 / 100.0);
    return t;
  }();
  const int ch = chroma_.empty() ? 1 : 3;
  std::vector<double> roofs;
  for (size_t r = 0; r < outlines_.size(); ++r) {
    if (!inside[r]) continue;
    const cv::Rect roi = cv::Rect(boxes[r].x - margin, boxes[r].y - margin, boxes[r].width + 2 * margin,
                                  boxes[r].height + 2 * margin) & frame;
    cv::Mat1b m(roi.size(), uchar(0));
    std::vector<cv::Point> local;
    for (const cv::Point& p : polys[r]) local.emplace_back(p.x - roi.x, p.y - roi.y);
    cv::fillPoly(m, std::vector<std::vector<cv::Point>>{local}, cv::Scalar(255));
    cv::Mat1b in, out, others;
    if (shrink > 0) cv::erode(m, in, k_in);
    else in = m;
    cv::dilate(m, out, k_ring);
    cv::dilate(all(roi), others, k_gap);
    out &= ~others;
    // mean and variance of the Lab values inside and in the ring
    double sum[2][3] = {}, sq[2][3] = {};
    int n[2] = {0, 0};
    for (int y = 0; y < roi.height; ++y) {
      const uchar* a = in.ptr<uchar>(y);
      const uchar* b = out.ptr<uchar>(y);
      const uchar* g = grey8_.ptr<uchar>(roi.y + y) + roi.x;
      const uchar* ab = ch == 3 ? chroma_.ptr<uchar>(std::min((roi.y + y) / 2, chroma_.rows - 1)) : nullptr;
      for (int x = 0; x < roi.width; ++x) {
        const int which = a[x] ? 0 : b[x] ? 1 : -1;
        if (which < 0) continue;
        ++n[which];
        double v[3] = {kLightness[g[x]], 0, 0};
        if (ab) {
          const int cx = std::min((roi.x + x) / 2, chroma_.cols - 1);
          v[1] = ab[2 * cx], v[2] = ab[2 * cx + 1];
        }
        for (int c = 0; c < ch; ++c) sum[which][c] += v[c], sq[which][c] += v[c] * v[c];
      }
    }
    if (n[0] < 4 || n[1] < 8) continue;
    double d2 = 0, var = 0;
    for (int c = 0; c < ch; ++c) {
      const double m0 = sum[0][c] / n[0], m1 = sum[1][c] / n[1];
      d2 += (m0 - m1) * (m0 - m1);
      var += std::max(0.0, sq[0][c] / n[0] - m0 * m0) + std::max(0.0, sq[1][c] / n[1] - m1 * m1);
    }
    constexpr double kNoiseVar = 4.0;  // 2 grey levels: a flat roof on flat ground is not infinitely clear
    roofs.push_back(std::sqrt(d2) / std::sqrt(var / 2 + kNoiseVar));
  }
  if (roofs.empty()) return;
  std::nth_element(roofs.begin(), roofs.begin() + roofs.size() / 2, roofs.end());
  double med = roofs[roofs.size() / 2];
  if (roofs.size() % 2 == 0) {
    const double lo = *std::max_element(roofs.begin(), roofs.begin() + roofs.size() / 2);
    med = 0.5 * (med + lo);
  }
  s->roof_regions = int(roofs.size());
  s->roof_contrast = med;
}

EdgeScore EdgeEvidence::Evaluate(const cv::Matx33d& photo_to_depth, cv::Point2d lean, int stride) const {
  Require(stride >= 1, ErrorCode::kInvalidArgument, "EdgeEvidence::Evaluate: stride must be >= 1");
  EdgeScore s;
  const cv::Matx33d S(photo_scale_, 0, 0, 0, photo_scale_, 0, 0, 0, 1);
  const cv::Matx33d D = S * photo_to_depth.inv();
  int n0 = 0, n1 = 0, n2 = 0;
  std::vector<double> on_r(size_t(regions_), 0.0), off_r(size_t(regions_), 0.0);
  std::vector<int> n_on(size_t(regions_), 0), n_off(size_t(regions_), 0);
  s.on = OnEdge(D, lean, 0, opt_.search_px, &n0, nullptr, &on_r, &n_on, stride);
  const double a = OnEdge(D, lean, -opt_.offset_px, opt_.search_px, &n1, nullptr, &off_r, &n_off, stride);
  const double b = OnEdge(D, lean, opt_.offset_px, opt_.search_px, &n2, nullptr, &off_r, &n_off, stride);
  n0 *= stride;  // counts as if every sample had been scored
  for (int r = 0; r < regions_; ++r) {
    if (n_on[size_t(r)] * stride < opt_.min_region_points) continue;
    ++s.regions;
    const double on = on_r[size_t(r)] / n_on[size_t(r)], off = off_r[size_t(r)] / std::max(1, n_off[size_t(r)]);
    if (on >= opt_.min_region_contrast * std::max(off, 1e-6)) ++s.regions_on_edges;
  }
  s.off = 0.5 * (a + b);
  s.points = n0;
  s.enough = n0 >= opt_.min_points;
  s.contrast = s.enough ? s.on / std::max(s.off, 1e-6) : 0;
  return s;
}

double EdgeEvidence::MeanGap(const cv::Matx33d& a, const cv::Matx33d& b, int stride) const {
  Require(stride >= 1, ErrorCode::kInvalidArgument, "EdgeEvidence::MeanGap: stride must be >= 1");
  const cv::Matx33d ai = a.inv();
  const double w = grey_.cols / photo_scale_, h = grey_.rows / photo_scale_;
  double sum = 0;
  int n = 0;
  for (size_t i = 0; i < samples_.size(); i += size_t(stride)) {
    const cv::Point2d q(samples_[i].q);
    const cv::Point2d p = Map(ai, q);
    if (!(p.x >= 0 && p.y >= 0 && p.x < w && p.y < h)) continue;
    const double d = cv::norm(Map(b, p) - q);
    if (!std::isfinite(d)) return std::numeric_limits<double>::infinity();
    sum += d, ++n;
  }
  return n ? sum / n : 0.0;
}

cv::Matx33d EdgeEvidence::Refine(const cv::Matx33d& photo_to_depth, bool perspective, bool sharp,
                                 const cv::Rect2d* support, cv::Point2d* lean) const {
  return RefineImpl(photo_to_depth, perspective, sharp, support, lean, /*estimate_lean=*/true, 1);
}

bool EdgeEvidence::LeanDetermined(const cv::Matx33d& D0, cv::Point2d lean0, const cv::Rect2d* support) const {
  if (!has_heights_) return false;
  const float w = float(grey_.cols), h = float(grey_.rows);
  std::vector<float> region_h(size_t(regions_), -1.f);  // height of each outline in view
  for (const Sample& s : samples_) {
    if (support && !support->contains(cv::Point2d(s.q))) continue;
    const cv::Point2d p = Map(D0, cv::Point2d(s.q) + lean0 * double(s.h));
    if (p.x < 0 || p.y < 0 || p.x >= w || p.y >= h) continue;
    region_h[size_t(s.region)] = s.h;
  }
  int k = 0;
  float h0 = std::numeric_limits<float>::infinity(), h1 = -h0;
  for (float rh : region_h)
    if (rh >= 0) ++k, h0 = std::min(h0, rh), h1 = std::max(h1, rh);
  return k >= opt_.min_lean_outlines && h1 - h0 >= opt_.min_lean_height_spread_m;
}

cv::Matx33d EdgeEvidence::RefineImpl(const cv::Matx33d& photo_to_depth, bool perspective, bool sharp,
                                     const cv::Rect2d* support, cv::Point2d* lean, bool estimate_lean,
                                     int stride) const {
  const cv::Matx33d S(photo_scale_, 0, 0, 0, photo_scale_, 0, 0, 0, 1);
  // the outline points in view define the frame of the correction
  int n = 0;
  const cv::Matx33d D0 = S * photo_to_depth.inv();
  const cv::Point2d lean0 = lean ? *lean : cv::Point2d();
  if (OnEdge(D0, lean0, 0, 0, &n, support, nullptr, nullptr, stride), n * stride < opt_.min_points)
    return photo_to_depth;
  const float w = float(grey_.cols), h = float(grey_.rows);
  cv::Point2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const Sample& s : samples_) {
    if (support && !support->contains(cv::Point2d(s.q))) continue;
    const cv::Point2d p = Map(D0, cv::Point2d(s.q) + lean0 * double(s.h));
    if (p.x < 0 || p.y < 0 || p.x >= w || p.y >= h) continue;
    lo.x = std::min(lo.x, double(s.q.x)), lo.y = std::min(lo.y, double(s.q.y));
    hi.x = std::max(hi.x, double(s.q.x)), hi.y = std::max(hi.y, double(s.q.y));
  }
  if (!(hi.x - lo.x > 4 && hi.y - lo.y > 4)) return photo_to_depth;
  // Correction C in depth space, T' = C * T, given by where it moves the 4
  // corners of the outlines' bounding box (8 parameters, depth px). The
  // similarity stage moves them together (translation, rotation, scale).
  const std::vector<cv::Point2f> box = {cv::Point2f(float(lo.x), float(lo.y)), cv::Point2f(float(hi.x), float(lo.y)),
                                        cv::Point2f(float(hi.x), float(hi.y)), cv::Point2f(float(lo.x), float(hi.y))};
  const cv::Point2f c = (box[0] + box[2]) * 0.5f;
  auto correction = [&](const std::vector<double>& d) {
    std::vector<cv::Point2f> moved(4);
    for (int i = 0; i < 4; ++i) moved[i] = box[i] + cv::Point2f(float(d[2 * i]), float(d[2 * i + 1]));
    return cv::Matx33d(cv::getPerspectiveTransform(box, moved));
  };
  // Parameters: the 8 corner moves, then the lean's change (2, as the
  // displacement of a roof at the reference height, depth px).
  constexpr int kParams = 10;
  // The lean needs outlines of several heights in view: with few, or of
  // like heights, it is a translation with two more ways to fit noise.
  const bool with_lean = lean && estimate_lean && opt_.max_lean_px_per_m > 0 && LeanDetermined(D0, lean0, support);
  auto lean_of = [&](const std::vector<double>& d) {
    return with_lean ? lean0 + cv::Point2d(d[8], d[9]) * (1.0 / ref_height_) : lean0;
  };
  double search = opt_.search_px;  // coarse: an edge anywhere in the window counts (wide basin)
  auto score = [&](const std::vector<double>& d) {
    const cv::Point2d l = lean_of(d);
    if (with_lean && std::hypot(l.x, l.y) > opt_.max_lean_px_per_m) return 0.0;
    const cv::Matx33d T = correction(d) * photo_to_depth;
    int m = 0;
    const double v = OnEdge(S * T.inv(), l, 0, search, &m, support, nullptr, nullptr, stride);
    return m * stride >= opt_.min_points ? v * std::min(1.0, double(m) / n) : 0.0;  // don't win by leaving the photo
  };
  std::vector<double> d(kParams, 0.0);
  double best = 0;
  // similarity moves of the 4 corners: translation x/y, rotation, scale;
  // k = 4, 5: the lean (x, y)
  auto similarity_move = [&](int k, double step) {
    std::vector<double> m(kParams, 0.0);
    if (k >= 4) {
      // a lean change about the reference height: roofs of that height
      // stay, lower and higher ones move apart (the fit before it has put
      // the mean roof where it is; a lean move alone would shift them all)
      m[size_t(8 + k - 4)] = step;
      for (int i = 0; i < 4; ++i) m[size_t(2 * i + k - 4)] = step;
      return m;
    }
    for (int i = 0; i < 4; ++i) {
      const cv::Point2f r = box[i] - c;
      double dx = 0, dy = 0;
      if (k == 0) dx = step;
      else if (k == 1) dy = step;
      else if (k == 2) dx = -r.y * step / std::max(1.0, cv::norm(r)), dy = r.x * step / std::max(1.0, cv::norm(r));
      else dx = r.x * step / std::max(1.0, cv::norm(r)), dy = r.y * step / std::max(1.0, cv::norm(r));
      m[2 * i] = dx, m[2 * i + 1] = dy;
    }
    return m;
  };
  auto ascend = [&](int dims, auto move, double step, double min_step) {
    for (int guard = 0; step >= min_step && guard < 200; ++guard) {
      bool improved = false;
      for (int k = 0; k < dims; ++k)
        for (double sgn : {1.0, -1.0}) {
          const std::vector<double> m = move(k, sgn * step);
          std::vector<double> t = d;
          for (int i = 0; i < kParams; ++i) t[size_t(i)] += m[size_t(i)];
          const double v = score(t);
          if (v > best * (1 + 1e-4)) best = v, d = t, improved = true;
        }
      if (!improved) step *= 0.5;
    }
  };
  auto corner_move = [](int k, double step) {
    std::vector<double> m(kParams, 0.0);
    m[k] = step;
    return m;
  };
  // coarse (window search, capture from a few px), then sharp (sampled on
  // the outline, so the optimum is the edge itself)
  for (double stage_search : {opt_.search_px, 0.0}) {
    if (stage_search == 0 && !sharp) break;
    search = stage_search;
    best = score(d);
    const double first = stage_search > 0 ? 2.0 : 0.5, last = stage_search > 0 ? 0.5 : 0.125;
    ascend(4, similarity_move, first, last);
    if (with_lean) {
      // the lean must earn its keep: with like heights it is a translation
      const std::vector<double> kept = d;
      const double before = best;
      ascend(6, similarity_move, first, last);
      if (best < before * (1 + opt_.min_lean_gain)) d = kept, best = before;
    }
    if (perspective && (stage_search == 0 || support)) {
      // the 8 parameters must earn their keep: few or bunched outlines let
      // them tilt the plane for a marginal gain
      const std::vector<double> kept = d;
      const double before = best;
      ascend(8, corner_move, first, last);
      if (best < before * (1 + opt_.min_perspective_gain)) d = kept, best = before;
    }
  }
  if (lean) *lean = lean_of(d);
  return correction(d) * photo_to_depth;
}

// One relocation step (see Relocate): false when too few cells could be
// measured or no homography fits them.
bool EdgeEvidence::RelocateOnce(const cv::Matx33d& photo_to_depth, cv::Point2d lean, bool perspective,
                                cv::Matx33d* T_out, cv::Point2d* lean_out) const {
  const cv::Matx33d S(photo_scale_, 0, 0, 0, photo_scale_, 0, 0, 0, 1);
  const cv::Matx33d D0 = S * photo_to_depth.inv();
  const float w = float(grey_.cols), h = float(grey_.rows);
  cv::Point2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const Sample& s : samples_) {
    const cv::Point2d p = Map(D0, cv::Point2d(s.q) + lean * double(s.h));
    if (p.x < 0 || p.y < 0 || p.x >= w || p.y >= h) continue;
    lo.x = std::min(lo.x, double(s.q.x)), lo.y = std::min(lo.y, double(s.q.y));
    hi.x = std::max(hi.x, double(s.q.x)), hi.y = std::max(hi.y, double(s.q.y));
  }
  if (!(hi.x - lo.x > 4 && hi.y - lo.y > 4)) return false;
  const cv::Matx33d Ti = photo_to_depth.inv();
  const int cells = opt_.relocate_cells;
  const int need = std::max(20, opt_.min_points / 3);  // samples in view for a cell's verdict
  const int k = int(std::floor(opt_.relocate_radius_px / opt_.relocate_grid_px));
  std::vector<cv::Point2f> from, to;  // photo (contour px) -> depth px, one per cell
  const double cw = (hi.x - lo.x) / cells, ch = (hi.y - lo.y) / cells;
  for (int cy = 0; cy < cells; ++cy)
    for (int cx = 0; cx < cells; ++cx) {
      const cv::Rect2d cell(lo.x + cx * cw, lo.y + cy * ch, cw, ch);
      int n0 = 0;
      OnEdge(D0, lean, 0, opt_.search_px, &n0, &cell);
      if (n0 < need) continue;
      double best = -1;
      cv::Point2d bd;
      for (int iy = -k; iy <= k; ++iy)
        for (int ix = -k; ix <= k; ++ix) {
          const cv::Point2d d(ix * opt_.relocate_grid_px, iy * opt_.relocate_grid_px);
          if (std::hypot(d.x, d.y) > opt_.relocate_radius_px) continue;
          const cv::Matx33d T = cv::Matx33d(1, 0, d.x, 0, 1, d.y, 0, 0, 1) * photo_to_depth;
          int m = 0;
          const double v = OnEdge(S * T.inv(), lean, 0, opt_.search_px, &m, &cell);
          if (m < need) continue;
          const double vv = v * std::min(1.0, double(m) / n0);  // don't win by leaving the photo
          if (vv > best) best = vv, bd = d;
        }
      if (best < 0) continue;
      const cv::Matx33d Tc =
          Refine(cv::Matx33d(1, 0, bd.x, 0, 1, bd.y, 0, 0, 1) * photo_to_depth, false, true, &cell, nullptr);
      const cv::Point2d p = Map(Ti, cv::Point2d(cell.x + cell.width / 2, cell.y + cell.height / 2));
      from.emplace_back(p), to.emplace_back(Map(Tc, p));
    }
  if (from.size() < 4) return false;
  const cv::Mat H = cv::findHomography(from, to, cv::RANSAC, 3.0, cv::noArray(), 2000, 0.999);
  if (H.empty()) return false;
  *lean_out = lean;
  *T_out = Refine(cv::Matx33d(H), perspective, true, nullptr, lean_out);
  return true;
}

EdgeEvidence::Relocation EdgeEvidence::Relocate(const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                                                bool perspective) const {
  Relocation out;
  out.photo_to_depth = photo_to_depth, out.lean = lean;
  out.edge = Evaluate(photo_to_depth, lean);
  if (!out.edge.enough) return out;
  for (int r = 0; r < opt_.relocate_rounds; ++r) {
    cv::Matx33d T;
    cv::Point2d l;
    if (!RelocateOnce(out.photo_to_depth, out.lean, perspective, &T, &l)) break;
    const EdgeScore e = Evaluate(T, l);
    if (!Accepts(e) || e.points < out.edge.points * 0.95 || e.on < (1 + opt_.relocate_min_gain) * out.edge.on) break;
    out.photo_to_depth = T, out.lean = l, out.edge = e, out.moved = true, ++out.rounds;
  }
  if (opt_.relocate_lean_gain > 0) {
    cv::Matx33d T;
    cv::Point2d l;
    EdgeScore e;
    if (LeanJump(out.photo_to_depth, out.lean, perspective, out.edge, &T, &l, &e))
      out.photo_to_depth = T, out.lean = l, out.edge = e, out.moved = true, out.lean_jumped = true;
  }
  if (out.moved) out.moved_px = MeanGap(photo_to_depth, out.photo_to_depth);
  return out;
}

bool EdgeEvidence::LeanJump(const cv::Matx33d& photo_to_depth, cv::Point2d lean, bool perspective,
                            const EdgeScore& e0, cv::Matx33d* T_out, cv::Point2d* lean_out, EdgeScore* e_out) const {
  const double lm = opt_.max_lean_px_per_m;
  const cv::Matx33d S(photo_scale_, 0, 0, 0, photo_scale_, 0, 0, 0, 1);
  if (lm <= 0 || !e0.enough || e0.regions < opt_.relocate_lean_outlines ||
      !LeanDetermined(S * photo_to_depth.inv(), lean, nullptr))
    return false;
  // the edge gain asked of a candidate: the lower one when roofs may decide
  const double gate = opt_.relocate_lean_roof_gain > 0 ? opt_.relocate_lean_min_gain : opt_.relocate_lean_gain;
  std::vector<cv::Point2d> leans;
  if (lean != cv::Point2d()) leans.emplace_back(0, 0);
  for (double r : {0.35, 0.7})
    for (int k = 0; k < 8; ++k) {
      const cv::Point2d c = lean + r * lm * cv::Point2d(std::cos(k * CV_PI / 4), std::sin(k * CV_PI / 4));
      if (std::hypot(c.x, c.y) <= lm) leans.push_back(c);
    }
  // no fewer outlines and samples in view: don't win by leaving the photo
  auto fair = [&](const EdgeScore& e) { return e.enough && e.regions >= e0.regions && e.points >= 0.95 * e0.points; };
  bool found = false;
  EdgeScore best;
  // Each lean's transform refined (every 2nd outline sample: 17 refits),
  // the best with all of them.
  for (cv::Point2d c : leans) {
    const cv::Matx33d T = RefineImpl(photo_to_depth, perspective, true, nullptr, &c, /*estimate_lean=*/false, 2);
    const EdgeScore e = Evaluate(T, c);
    if (fair(e) && e.on >= (1 + gate) * e0.on && (!found || e.on > best.on))
      found = true, best = e, *T_out = T, *lean_out = c;
  }
  if (!found) return false;
  *T_out = RefineImpl(*T_out, perspective, true, nullptr, lean_out, /*estimate_lean=*/false, 1);
  best = Evaluate(*T_out, *lean_out);
  if (!fair(best) || best.on < (1 + gate) * e0.on) return false;
  // the lean refined with the transform from there
  cv::Point2d l = *lean_out;
  const cv::Matx33d T2 = Refine(*T_out, perspective, true, nullptr, &l);
  const EdgeScore e2 = Evaluate(T2, l);
  if (fair(e2) && e2.on >= best.on) *T_out = T2, *lean_out = l, best = e2;
  // The lean polished: the rings are 0.28 max_lean_px_per_m apart, and
  // Refine keeps a lean change only when it earns min_lean_gain. A pattern
  // search over the lean, the roofs at the reference height held in place
  // (the transform shifted by ref_height x the lean's change), on the edge
  // response sampled on the outlines themselves (no window: sub-pixel moves
  // count).
  int m0 = 0;
  double sharp = OnEdge(S * T_out->inv(), *lean_out, 0, 0.0, &m0);
  for (double st = 0.1 * lm; st >= 0.0125 * lm; st *= 0.5)
    for (int moves = 0; moves < 8; ++moves) {
      bool improved = false;
      for (int k = 0; k < 8; ++k) {
        const cv::Point2d d = st * cv::Point2d(std::cos(k * CV_PI / 4), std::sin(k * CV_PI / 4));
        const cv::Point2d c = *lean_out + d;
        if (std::hypot(c.x, c.y) > lm) continue;
        const cv::Matx33d T = cv::Matx33d(1, 0, ref_height_ * d.x, 0, 1, ref_height_ * d.y, 0, 0, 1) * *T_out;
        int m = 0;
        const double v = OnEdge(S * T.inv(), c, 0, 0.0, &m);
        if (m >= m0 && v > sharp) *T_out = T, *lean_out = c, sharp = v, improved = true;
      }
      if (!improved) break;
    }
  best = Evaluate(*T_out, *lean_out);
  if (!fair(best) || best.on < (1 + gate) * e0.on) return false;
  // the roofs, independent of the edges, must agree
  EdgeScore r0 = e0;
  ScoreRoofs(photo_to_depth, lean, &r0);
  ScoreRoofs(*T_out, *lean_out, &best);
  // at the full edge gain the roofs must stand apart no less; below it,
  // clearly more (the best candidate is the same either way: the one whose
  // edges gain most)
  const bool edges_decide = best.on >= (1 + opt_.relocate_lean_gain) * e0.on;
  const bool roofs_decide =
      opt_.relocate_lean_roof_gain > 0 && best.roof_contrast >= (1 + opt_.relocate_lean_roof_gain) * r0.roof_contrast;
  if (r0.roof_regions < opt_.min_roof_regions || best.roof_regions < opt_.min_roof_regions ||
      best.roof_contrast < r0.roof_contrast || !Accepts(best) || !(edges_decide || roofs_decide))
    return false;
  *e_out = best;
  return true;
}

cv::Matx33d EdgeEvidence::RefineOutward(const cv::Matx33d& photo_to_depth, const cv::Rect2d& seed, bool perspective,
                                        cv::Point2d* lean) const {
  // the extent of all outlines
  cv::Point2d lo(1e18, 1e18), hi(-1e18, -1e18);
  for (const Sample& s : samples_)
    lo.x = std::min(lo.x, double(s.q.x)), lo.y = std::min(lo.y, double(s.q.y)),
    hi.x = std::max(hi.x, double(s.q.x)), hi.y = std::max(hi.y, double(s.q.y));
  cv::Matx33d T = photo_to_depth;
  cv::Rect2d box = seed;
  for (int step = 0; step < 12; ++step) {
    const bool all = box.x <= lo.x && box.y <= lo.y && box.br().x >= hi.x && box.br().y >= hi.y;
    T = Refine(T, perspective, /*sharp=*/all, all ? nullptr : &box, lean);
    if (all) break;
    const cv::Point2d c(box.x + box.width / 2, box.y + box.height / 2);
    const double gw = box.width * opt_.outward_growth, gh = box.height * opt_.outward_growth;
    box = cv::Rect2d(c.x - gw / 2, c.y - gh / 2, gw, gh);
  }
  return T;
}

}  // namespace mvkp
