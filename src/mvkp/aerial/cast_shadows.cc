#include "mvkp/aerial/cast_shadows.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>
#include <cstdio>
#include <cstdlib>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void CastShadowOptions::Check() const {
  Require(fit_max_side >= 64 && azimuths >= 8 && lengths >= 1 && min_length > 0 && max_length >= min_length &&
              std::isfinite(max_length),
          ErrorCode::kInvalidArgument,
          "CastShadowOptions: fit_max_side >= 64, azimuths >= 8, lengths >= 1, 0 < min_length <= max_length");
  Require(max_fraction > 0 && max_fraction <= 1, ErrorCode::kInvalidArgument,
          "CastShadowOptions.max_fraction must be in (0, 1]");
  Require(min_height_m >= 0 && min_buildings >= 1 && ring_px > 0 && min_contrast >= 0 && min_margin >= 0 &&
              grow_px >= 0 && feather_sigma >= 0,
          ErrorCode::kInvalidArgument,
          "CastShadowOptions: min_height_m, min_contrast, min_margin, grow_px, feather_sigma >= 0; "
          "min_buildings >= 1; ring_px > 0");
}

namespace {

constexpr int kShift = 4;  // sub-pixel bits of the rasterisation
constexpr double kOne = 1 << kShift;

// x' = (x + 0.5) * s - 0.5: pixel centres at integers, scaled by s.
cv::Matx33d PixelScale(double s) { return {s, 0, 0.5 * s - 0.5, 0, s, 0.5 * s - 0.5, 0, 0, 1}; }

struct Caster {
  std::vector<cv::Point2d> poly;  // simplified outline, depth px
  double h = 0;                   // metres
};

bool Map(const cv::Matx33d& M, cv::Point2d q, cv::Point* out) {
  const cv::Vec3d v = M * cv::Vec3d(q.x, q.y, 1);
  if (!(v[2] > 1e-9)) return false;
  const double x = v[0] / v[2], y = v[1] / v[2];
  if (!(std::abs(x) < 1e6 && std::abs(y) < 1e6)) return false;
  *out = cv::Point(cvRound(x * kOne), cvRound(y * kOne));
  return true;
}

void FillPolygon(cv::Mat1b& m, const cv::Matx33d& M, const std::vector<cv::Point2d>& poly, cv::Point2d offset) {
  std::vector<cv::Point> p(poly.size());
  for (size_t i = 0; i < poly.size(); ++i)
    if (!Map(M, poly[i] + offset, &p[i])) return;
  const cv::Point* pts = p.data();
  const int n = int(p.size());
  cv::fillPoly(m, &pts, &n, 1, cv::Scalar(255), cv::LINE_8, kShift);
}

// The sweep of `c` along d (depth px): its edges' parallelograms and the
// outline at the far end (the outline itself is a roof: left out).
void FillShadow(cv::Mat1b& m, const cv::Matx33d& M, const Caster& c, cv::Point2d d) {
  const size_t n = c.poly.size();
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2d a = c.poly[i], b = c.poly[(i + 1) % n];
    cv::Point q[4];
    if (!Map(M, a, &q[0]) || !Map(M, b, &q[1]) || !Map(M, b + d, &q[2]) || !Map(M, a + d, &q[3])) continue;
    cv::fillConvexPoly(m, q, 4, cv::Scalar(255), cv::LINE_8, kShift);
  }
  FillPolygon(m, M, c.poly, d);
}

// Roofs (with the lean) and footprints of every building: where no cast
// shadow is counted or relit.
cv::Mat1b Occupied(cv::Size size, const cv::Matx33d& M, const std::vector<Caster>& all, cv::Point2d lean) {
  cv::Mat1b f(size, uchar(0));
  for (const auto& c : all) {
    FillPolygon(f, M, c.poly, {0, 0});
    if (lean.x != 0 || lean.y != 0) {
      FillPolygon(f, M, c.poly, lean * c.h);
      FillShadow(f, M, c, lean * c.h);  // the walls between, as the leaning photo shows them
    }
  }
  return f;
}

cv::Mat1b Shadows(cv::Size size, const cv::Matx33d& M, const std::vector<Caster>& casters, cv::Point2d u, double k,
                  const cv::Mat1b& occupied) {
  cv::Mat1b s(size, uchar(0));
  for (const auto& c : casters) FillShadow(s, M, c, u * (c.h * k));
  s.setTo(0, occupied);
  return s;
}

cv::Mat1b Ring(const cv::Mat1b& shadows, const cv::Mat1b& occupied, double px) {
  const int r = std::max(1, int(std::lround(px)));
  cv::Mat1b ring;
  cv::dilate(shadows, ring, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)));
  ring.setTo(0, shadows);
  ring.setTo(0, occupied);
  return ring;
}

// log(grey + 4) of an 8-bit BGR image.
cv::Mat1f LogGrey(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::Mat1f logy;
  grey.convertTo(logy, CV_32F, 1.0, 4.0);
  cv::log(logy, logy);
  return logy;
}

// Mean log grey level over a mask, and the pixels counted.
double MaskMean(const cv::Mat1f& v, const cv::Mat1b& m, int* count) {
  *count = cv::countNonZero(m);
  return *count ? cv::mean(v, m)[0] : 0.0;
}

// Steps 1-3 (see the header); `casters_out`, `all_out`: the buildings, for
// the relighting. False with out->reason when no sun is fitted.
bool Fit(const cv::Mat& photo, double f, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
         const std::vector<BuildingRegion>& buildings, const CastShadowOptions& o, CastShadowFit* fit,
         std::vector<Caster>* casters_out, std::vector<Caster>* all_out) {
  Timer timer;
  CastShadowFit& out = *fit;
  out = CastShadowFit{};
  auto refuse = [&](const std::string& why) {
    out.reason = why;
    out.ms = timer.ElapsedMs();
    return false;
  };
  if (photo.empty() || photo.type() != CV_8UC3) return refuse("not an 8-bit BGR photo");
  if (!(f > 0) || std::abs(cv::determinant(photo_to_depth)) < 1e-12) return refuse("no pose");

  // depth px -> working px, and -> the fit's small copy
  const cv::Matx33d to_working = PixelScale(f) * photo_to_depth.inv();
  const double g = std::min(1.0, double(o.fit_max_side) / std::max(photo.cols, photo.rows));
  const cv::Matx33d to_fit = PixelScale(g) * to_working;
  cv::Mat small;
  if (g < 1) cv::resize(photo, small, cv::Size(), g, g, cv::INTER_AREA);
  else small = photo;
  const cv::Rect view(0, 0, small.cols, small.rows);

  std::vector<Caster> all, casters;
  for (const auto& b : buildings) {
    if (b.contour.size() < 3) continue;
    std::vector<cv::Point> simple;
    cv::approxPolyDP(b.contour, simple, 1.0, true);
    if (simple.size() < 3) continue;
    Caster c;
    for (const auto& p : simple) c.poly.emplace_back(p.x, p.y);
    c.h = std::max(0.f, b.height);
    all.push_back(c);
    if (c.h < o.min_height_m) continue;
    cv::Point centre;
    const cv::Rect2d box = cv::boundingRect(simple);
    if (Map(to_fit, {box.x + box.width / 2, box.y + box.height / 2}, &centre) &&
        view.contains(cv::Point(centre.x >> kShift, centre.y >> kShift)))
      casters.push_back(c), ++out.buildings;
  }
  if (out.buildings < o.min_buildings)
    return refuse(cv::format("%d buildings in view cast shadows (%d needed)", out.buildings, o.min_buildings));

  const cv::Mat1f logy = LogGrey(small);
  const cv::Mat1b occupied = Occupied(small.size(), to_fit, all, lean);
  const int min_pixels = std::max(20, int(0.002 * small.total()));

  // 1. the sun: every azimuth x length
  std::vector<double> ks(o.lengths);
  for (int j = 0; j < o.lengths; ++j)
    ks[j] = o.lengths == 1 ? o.min_length
                           : o.min_length * std::pow(o.max_length / o.min_length, double(j) / (o.lengths - 1));
  // Coarse to fine: every azimuth at every third length; a pose whose
  // shadows do not come near standing out stops there (most candidates are
  // wrong); then every length at the best azimuth and its neighbours, and
  // every azimuth at the length chosen, for the margin.
  const double kUnset = -1e9;
  cv::Mat1d score(o.lengths, o.azimuths, kUnset);
  cv::Mat1b done(o.lengths, o.azimuths, uchar(0));
  auto eval = [&](int j, int a) {
    if (done(j, a)) return;
    done(j, a) = 1;
    const double t = 2 * CV_PI * a / o.azimuths;
    const cv::Mat1b s = Shadows(small.size(), to_fit, casters, {std::sin(t), -std::cos(t)}, ks[j], occupied);
    const cv::Mat1b r = Ring(s, occupied, o.ring_px);
    int ns = 0, nr = 0;
    const double ms = MaskMean(logy, s, &ns), mr = MaskMean(logy, r, &nr);
    if (ns >= min_pixels && nr >= min_pixels) score(j, a) = mr - ms;
  };
  cv::Point best;
  double top = 0, median = 0;
  auto pick = [&] {
    cv::minMaxLoc(score, nullptr, &top, nullptr, &best);
    std::vector<double> others;
    for (int a = 0; a < o.azimuths; ++a)
      if (a != best.x && score(best.y, a) > kUnset / 2) others.push_back(score(best.y, a));
    median = 0;
    if (!others.empty()) {
      std::nth_element(others.begin(), others.begin() + others.size() / 2, others.end());
      median = others[others.size() / 2];
    }
  };
  for (int j = 0; j < o.lengths; ++j)
    if (j % 3 == 0 || j == o.lengths - 1)
      for (int a = 0; a < o.azimuths; ++a) eval(j, a);
  pick();
  if (top <= kUnset / 2) return refuse("the predicted shadows fall outside the photo");
  if (top >= 0.75 * o.min_contrast && top - median >= 0.6 * o.min_margin) {
    for (int da = -1; da <= 1; ++da)
      for (int j = 0; j < o.lengths; ++j) eval(j, (best.x + da + o.azimuths) % o.azimuths);
    pick();
    for (int a = 0; a < o.azimuths; ++a) eval(best.y, a);
    pick();
  }
  out.azimuth_deg = 360.0 * best.x / o.azimuths;
  out.length_px_per_m = ks[best.y];
  out.contrast = top;
  out.margin = top - median;
  // an optimum at the longest length tried is no length found (the
  // predicted shadows then reach over whatever dark ground lies beyond)
  if (o.lengths > 1 && best.y == o.lengths - 1)
    return refuse(cv::format("the shadows' length is not bounded (darkest at the longest tried, %.1f depth px per m)",
                             o.max_length));
  if (out.contrast < o.min_contrast || out.margin < o.min_margin)
    return refuse(cv::format("no sun stands out (shadow darkness %.3f, %.3f above the median azimuth; %.2f and %.2f "
                             "needed)",
                             out.contrast, out.margin, o.min_contrast, o.min_margin));
  const double t = 2 * CV_PI * best.x / o.azimuths;
  const cv::Point2d u(std::sin(t), -std::cos(t));

  // 3. the step per channel: the shadows' dark pixels against the ring
  {
    const cv::Mat1b s = Shadows(small.size(), to_fit, casters, u, ks[best.y], occupied);
    const cv::Mat1b r = Ring(s, occupied, o.ring_px);
    int nr = 0;
    const double mr = MaskMean(logy, r, &nr);
    cv::Mat1b dark = s & (logy < mr - 0.5 * out.contrast);
    cv::Mat lc;
    small.convertTo(lc, CV_32FC3, 1.0, 4.0);
    cv::log(lc, lc);
    if (cv::countNonZero(dark) < min_pixels / 2) return refuse("too few dark pixels in the predicted shadows");
    const cv::Scalar in = cv::mean(lc, dark), ring = cv::mean(lc, r);
    for (int c = 0; c < 3; ++c) out.log_step[c] = in[c] - ring[c];
    if (!(out.log_step[0] < 0 && out.log_step[1] < 0 && out.log_step[2] < 0))
      return refuse(cv::format("the predicted shadows do not darken every channel (step %.2f %.2f %.2f)",
                               out.log_step[0], out.log_step[1], out.log_step[2]));
  }

  out.found = true;
  out.ms = timer.ElapsedMs();
  *casters_out = std::move(casters);
  *all_out = std::move(all);
  return true;
}

}  // namespace

CastShadowFit FitCastShadows(const cv::Mat& photo, double f, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                             const std::vector<BuildingRegion>& buildings, const CastShadowOptions& o) {
  o.Check();
  CastShadowFit fit;
  std::vector<Caster> casters, all;
  Fit(photo, f, photo_to_depth, lean, buildings, o, &fit, &casters, &all);
  return fit;
}

cv::Mat RelightCastShadows(const cv::Mat& photo, double f, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                           const std::vector<BuildingRegion>& buildings, const CastShadowOptions& o,
                           CastShadowFit* fit) {
  o.Check();
  Timer timer;
  CastShadowFit local;
  CastShadowFit& out = fit ? *fit : local;
  std::vector<Caster> casters, all;
  if (!Fit(photo, f, photo_to_depth, lean, buildings, o, &out, &casters, &all)) return photo;
  const cv::Matx33d to_working = PixelScale(f) * photo_to_depth.inv();
  const double g = std::min(1.0, double(o.fit_max_side) / std::max(photo.cols, photo.rows));
  const double t = out.azimuth_deg * CV_PI / 180;
  const cv::Point2d u(std::sin(t), -std::cos(t));
  const double k = out.length_px_per_m;
  // 4. relit at the working size: the predicted shadows, grown for the
  // pose's error, where darker than the ring near them by half the step.
  // The lit level near each pixel (the ring's mean over a window) comes
  // from the fit's small copy: 8-bit maps only at the working size.
  cv::Mat small;
  if (g < 1) cv::resize(photo, small, cv::Size(), g, g, cv::INTER_AREA);
  else small = photo;
  const cv::Matx33d to_fit = PixelScale(g) * to_working;
  const cv::Matx22d J(to_working(0, 0), to_working(0, 1), to_working(1, 0), to_working(1, 1));
  const double px_per_depth = std::sqrt(std::abs(cv::determinant(J))) /
                              std::max(1e-9, std::abs(to_working(2, 2)));  // a nadir pose is near affine
  const int grow = int(std::lround(o.grow_px * px_per_depth));
  cv::Mat1f lit_small;
  float global = 0;
  {
    const cv::Mat1f logy = LogGrey(small);
    const cv::Mat1b occ_s = Occupied(small.size(), to_fit, all, lean);
    const cv::Mat1b ring = Ring(Shadows(small.size(), to_fit, casters, u, k, occ_s), occ_s, o.ring_px);
    const int win = 2 * std::max(4, int(std::lround(4 * o.ring_px + grow * g))) + 1;
    cv::Mat1f rf, sum, cnt;
    ring.convertTo(rf, CV_32F, 1.0 / 255);
    cv::boxFilter(logy.mul(rf), sum, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false);
    cv::boxFilter(rf, cnt, CV_32F, cv::Size(win, win), cv::Point(-1, -1), false);
    int nr = 0;
    global = float(MaskMean(logy, ring, &nr));
    lit_small.create(small.size());
    for (int y = 0; y < small.rows; ++y)
      for (int x = 0; x < small.cols; ++x) {
        const float c = cnt(y, x);
        lit_small(y, x) = c >= 1.0f ? sum(y, x) / c : global;
      }
  }
  small.release();
  const cv::Mat1b occ_w = Occupied(photo.size(), to_working, all, lean);
  cv::Mat1b s_w = Shadows(photo.size(), to_working, casters, u, k, occ_w);
  if (grow > 0)
    cv::dilate(s_w, s_w, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * grow + 1, 2 * grow + 1)));
  s_w.setTo(0, occ_w);
  float log_lut[256];
  for (int v = 0; v < 256; ++v) log_lut[v] = std::log(v + 4.0f);
  const float half_step = float((out.log_step[0] + out.log_step[1] + out.log_step[2]) / 6);
  cv::Mat1b grey_w;
  cv::cvtColor(photo, grey_w, cv::COLOR_BGR2GRAY);
  cv::Mat1b m(photo.size(), uchar(0));
  for (int y = 0; y < photo.rows; ++y) {
    const uchar *sp = s_w.ptr<uchar>(y), *gp = grey_w.ptr<uchar>(y);
    uchar* mp = m.ptr<uchar>(y);
    const int ys = std::clamp(int(std::lround((y + 0.5) * g - 0.5)), 0, lit_small.rows - 1);
    const float* lp = lit_small.ptr<float>(ys);
    for (int x = 0; x < photo.cols; ++x) {
      if (!sp[x]) continue;
      const int xs = std::clamp(int(std::lround((x + 0.5) * g - 0.5)), 0, lit_small.cols - 1);
      mp[x] = log_lut[gp[x]] < lp[xs] + half_step ? 255 : 0;
    }
  }
  grey_w.release(), s_w.release();
  cv::medianBlur(m, m, 3);
  out.fraction = cv::countNonZero(m) / double(m.total());
  if (out.fraction > o.max_fraction) {
    out.reason = cv::format("%.0f %% of the photo would be relit (at most %.0f %%)", 100 * out.fraction,
                            100 * o.max_fraction);
    out.ms = timer.ElapsedMs();
    return photo;
  }
  if (o.feather_sigma > 0) cv::GaussianBlur(m, m, cv::Size(), o.feather_sigma);
  cv::Mat relit = photo.clone();
  float gain[3][256];  // (v + 4) * exp(-d * w) - 4 at w = 1, per channel; blended by the feathered weight
  for (int c = 0; c < 3; ++c)
    for (int v = 0; v < 256; ++v) gain[c][v] = (v + 4.0f) * std::exp(-float(out.log_step[c])) - 4.0f;
  for (int y = 0; y < photo.rows; ++y) {
    const uchar* mp = m.ptr<uchar>(y);
    cv::Vec3b* op = relit.ptr<cv::Vec3b>(y);
    for (int x = 0; x < photo.cols; ++x) {
      if (!mp[x]) continue;
      const float w = mp[x] / 255.0f;
      for (int c = 0; c < 3; ++c) {
        // the exponent blended as ortho/shadows.cc does: (I + 4) * exp(-d * w) - 4
        const float v = op[x][c];
        op[x][c] = cv::saturate_cast<uchar>(w >= 1 ? gain[c][op[x][c]]
                                                   : (v + 4.0f) * std::exp(-float(out.log_step[c]) * w) - 4.0f);
      }
    }
  }
  out.applied = true;
  out.ms = timer.ElapsedMs();
  return relit;
}

}  // namespace mvkp
