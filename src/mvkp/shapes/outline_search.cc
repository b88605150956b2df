#include "mvkp/shapes/outline_search.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void OutlineSearchOptions::Check() const {
  auto need = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, m); };
  need(min_scale > 0 && max_scale > min_scale, "OutlineSearchOptions: need 0 < min_scale < max_scale");
  need(scale_hint >= 0 && scale_hint_tolerance > 0 && scale_hint_tolerance < 1,
       "OutlineSearchOptions: scale_hint >= 0, scale_hint_tolerance in (0, 1)");
  need(min_extent_ratio > 0 && max_extent_ratio > min_extent_ratio,
       "OutlineSearchOptions: need 0 < min_extent_ratio < max_extent_ratio");
  need(cells_per_building >= 1 && max_template_radius >= 8 && step_factor > 0,
       "OutlineSearchOptions: cells_per_building >= 1, max_template_radius >= 8, step_factor > 0");
  need(rotation_peaks >= 1 && rotation_window_deg >= 0 && min_rotation_peakiness >= 1,
       "OutlineSearchOptions: rotation_peaks >= 1, rotation_window_deg >= 0, min_rotation_peakiness >= 1");
  need(min_overlap >= 0 && min_overlap <= 1 && min_samples >= 1,
       "OutlineSearchOptions: min_overlap in [0, 1], min_samples >= 1");
  need(min_on_edges >= 0 && min_on_edges <= 1, "OutlineSearchOptions: min_on_edges in [0, 1]");
  need(coarse_candidates >= 2 && distinct_px > 0, "OutlineSearchOptions: coarse_candidates >= 2, distinct_px > 0");
  need(min_outlines >= 1, "OutlineSearchOptions.min_outlines must be >= 1");
  need(min_confidence >= 0 && min_confidence <= 1, "OutlineSearchOptions.min_confidence in [0, 1]");
  need(object_weight >= 0 && object_weight <= 1 && completeness_power >= 0 && completeness_power <= 4,
       "OutlineSearchOptions: object_weight in [0, 1], completeness_power in [0, 4]");
  need(min_completeness >= 0 && min_completeness <= 1, "OutlineSearchOptions.min_completeness in [0, 1]");
}

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Sample {
  cv::Point2f q;   // depth px
  cv::Point2f n;   // unit normal
  float psi = 0;   // normal angle, rad
  int b = 0;       // outline index (-1: an object, not a building)
  float w = 1;     // weight in the score
};

// Outline samples every `step` px of arc length, normals from the neighbours.
std::vector<Sample> SampleOutlines(const std::vector<Contour>& outlines, double step) {
  std::vector<Sample> out;
  int index = -1;
  for (const Contour& c : outlines) {
    ++index;
    if (c.size() < 3) continue;
    std::vector<cv::Point2f> pts;
    double carry = 0;
    for (size_t i = 0, n = c.size(); i < n; ++i) {
      const cv::Point2f a = c[i], b = c[(i + 1) % n];
      const double len = cv::norm(b - a);
      double t = carry;
      for (; t < len; t += step) pts.push_back(a + (b - a) * float(t / len));
      carry = t - len;
    }
    const size_t n = pts.size();
    if (n < 6) continue;
    for (size_t i = 0; i < n; ++i) {
      // normal from a wider baseline: pixel contours are staircases
      const cv::Point2f d = pts[(i + 2) % n] - pts[(i + n - 2) % n];
      const double len = cv::norm(d);
      if (len < 1e-6) continue;
      Sample s;
      s.q = pts[i];
      s.n = cv::Point2f(float(-d.y / len), float(d.x / len));
      s.psi = float(std::atan2(s.n.y, s.n.x));
      s.b = index;
      out.push_back(s);
    }
  }
  return out;
}

// Oriented edge field in the doubled-angle form, CV_32FC2: m_n (cos 2phi,
// sin 2phi), m_n = min(|grad| / mean |grad|, 4); blurred by `blur` px.
struct Field {
  cv::Mat P;      // CV_32FC2
  double k = 1;   // field px per image px: x = (u + 0.5) k - 0.5
  double v = 1;   // null variance of one sample's score
};

Field MakeField(const cv::Mat1f& grey, double k, double blur) {
  Field f;
  f.k = k;
  cv::Mat1f g;
  if (std::abs(k - 1) < 1e-9) g = grey;
  else cv::resize(grey, g, cv::Size(std::max(1, int(std::lround(grey.cols * k))), std::max(1, int(std::lround(grey.rows * k)))),
                  0, 0, k < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  cv::Mat1f gx, gy;
  cv::Sobel(g, gx, CV_32F, 1, 0, 3, 0.125);
  cv::Sobel(g, gy, CV_32F, 0, 1, 3, 0.125);
  cv::Mat1f m2 = gx.mul(gx) + gy.mul(gy);
  cv::Mat1f m;
  cv::sqrt(m2, m);
  const double mean = std::max(cv::mean(m)[0], 1e-3);
  f.P.create(g.size(), CV_32FC2);
  for (int y = 0; y < g.rows; ++y) {
    const float *px = gx.ptr<float>(y), *py = gy.ptr<float>(y), *pm = m.ptr<float>(y), *pm2 = m2.ptr<float>(y);
    cv::Vec2f* o = f.P.ptr<cv::Vec2f>(y);
    for (int x = 0; x < g.cols; ++x) {
      if (pm2[x] < 1e-12f) { o[x] = cv::Vec2f(0, 0); continue; }
      const float mn = std::min(float(pm[x] / mean), 4.0f);
      o[x] = cv::Vec2f(mn * (px[x] * px[x] - py[x] * py[x]) / pm2[x], mn * 2 * px[x] * py[x] / pm2[x]);
    }
  }
  if (blur > 0) cv::GaussianBlur(f.P, f.P, cv::Size(), blur);
  cv::Mat sq;
  cv::multiply(f.P, f.P, sq);
  const cv::Scalar s = cv::mean(sq);
  f.v = std::max((s[0] + s[1]) / 2, 1e-6);
  return f;
}

// Circular histogram of angles modulo 90 degrees (1-degree bins), smoothed.
std::vector<double> Smooth90(const std::vector<double>& h) {
  std::vector<double> o(90, 0.0);
  for (int i = 0; i < 90; ++i)
    for (int d = -4; d <= 4; ++d) o[size_t(i)] += h[size_t((i + d + 90) % 90)] * std::exp(-d * d / 8.0);
  return o;
}
inline int Bin90(double rad) {
  double deg = std::fmod(rad * 180 / kPi, 90.0);
  if (deg < 0) deg += 90;
  return std::min(89, int(deg));
}

inline cv::Point2d Map(const cv::Matx33d& H, cv::Point2d p) {
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  const double iw = std::abs(w) > 1e-12 ? 1.0 / w : 1e12;
  return {(H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) * iw, (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) * iw};
}

inline cv::Vec2f At2(const cv::Mat& m, float x, float y) {
  const int x0 = int(x), y0 = int(y);
  const float fx = x - float(x0), fy = y - float(y0);
  const cv::Vec2f* r0 = m.ptr<cv::Vec2f>(y0) + x0;
  const cv::Vec2f* r1 = m.ptr<cv::Vec2f>(y0 + 1) + x0;
  return (r0[0] * (1 - fx) + r0[1] * fx) * (1 - fy) + (r1[0] * (1 - fx) + r1[1] * fx) * fy;
}

struct Pose {
  cv::Matx33d T;  // contour photo px -> depth px
  double z = -1e18;
  double coverage = 0;
};

// Mean distance (depth px) between where two transforms put the photo points
// that the first maps onto `probe` (depth px).
double PoseDistance(const cv::Matx33d& A, const cv::Matx33d& B, const std::vector<cv::Point2d>& probe) {
  const cv::Matx33d Ai = A.inv();
  double s = 0;
  for (const auto& q : probe) {
    const cv::Point2d p = Map(Ai, q);
    s += cv::norm(Map(B, p) - q);
  }
  return s / double(probe.size());
}

}  // namespace

OutlineSearchResult SearchOutlines(const cv::Mat& photo, double ps, const std::vector<Contour>& outlines,
                                   const OutlineSearchOptions& opt, const EdgeEvidence* evidence,
                                   const std::vector<Contour>* objects) {
  const OutlineSearchOptions& o = opt;
  o.Check();
  Require(!photo.empty() && photo.depth() == CV_8U && (photo.channels() == 1 || photo.channels() == 3),
          ErrorCode::kInvalidArgument, "SearchOutlines: the photo must be 8-bit grey or BGR");
  Require(ps > 0 && std::isfinite(ps), ErrorCode::kInvalidArgument, "SearchOutlines: photo_scale must be > 0");
  Timer timer;
  OutlineSearchResult res;
  auto fail = [&](std::string why) {
    res.ok = false;
    res.reason = "no registration found: " + why;
    res.ms = timer.ElapsedMs();
    return res;
  };

  // ---- depth side: outline samples, building size, extent
  std::vector<Sample> samples = SampleOutlines(outlines, 1.0);
  if (int(samples.size()) < o.min_samples) return fail("too few building outlines in the depth image");
  const size_t building_samples = samples.size();  // the buildings' samples come first
  if (objects && o.object_weight > 0) {
    std::vector<Sample> more = SampleOutlines(*objects, 1.0);
    for (auto& m : more) m.b = -1, m.w = float(o.object_weight);  // never counted as an outline in view
    samples.insert(samples.end(), more.begin(), more.end());
  }
  std::vector<double> sides;
  for (const Contour& c : outlines)
    if (c.size() >= 3) sides.push_back(std::sqrt(std::abs(SignedArea(c))));
  std::nth_element(sides.begin(), sides.begin() + sides.size() / 2, sides.end());
  const double building = std::max(4.0, sides[sides.size() / 2]);
  float x0 = 1e30f, y0 = 1e30f, x1 = -1e30f, y1 = -1e30f;
  for (const auto& s : samples) x0 = std::min(x0, s.q.x), y0 = std::min(y0, s.q.y), x1 = std::max(x1, s.q.x), y1 = std::max(y1, s.q.y);
  const double ext_w = x1 - x0 + 1, ext_h = y1 - y0 + 1, extent = std::max(ext_w, ext_h);
  const cv::Point2d qc(0.5 * (x0 + x1), 0.5 * (y0 + y1));
  const std::vector<cv::Point2d> probe = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, qc};
  const double cell = std::max({1.0, building / o.cells_per_building, 0.5 * std::hypot(ext_w, ext_h) / o.max_template_radius});
  const double radius = 0.5 * std::hypot(ext_w, ext_h) / cell;  // template radius, cells
  const double step = o.step_factor / std::max(radius, 4.0);   // rad and log-scale
  const int Rt = int(std::ceil(radius)) + 2, Wt = 2 * Rt + 1;

  // ---- photo side
  cv::Mat1f grey;
  {
    cv::Mat g;
    if (photo.channels() == 3) cv::cvtColor(photo, g, cv::COLOR_BGR2GRAY);
    else g = photo;
    g.convertTo(grey, CV_32F);
  }
  const double photo_extent = std::max(grey.cols, grey.rows) / ps;  // contour px

  // scale range (depth px per photo contour px)
  double smin = o.min_scale, smax = o.max_scale;
  if (o.scale_hint > 0) smin = o.scale_hint * (1 - o.scale_hint_tolerance), smax = o.scale_hint * (1 + o.scale_hint_tolerance);
  smin = std::max(smin, o.min_extent_ratio * extent / photo_extent);
  smax = std::min(smax, o.max_extent_ratio * extent / photo_extent);
  if (!(smax >= smin)) return fail("the photo's extent does not fit the depth outlines at any allowed scale");
  std::vector<double> scales;
  for (double ls = std::log(smin); ls <= std::log(smax) + 1e-9; ls += step) scales.push_back(std::exp(ls));
  if (scales.empty()) scales.push_back(std::sqrt(smin * smax));

  // ---- rotation prior: outline normals vs photo gradients, modulo 90 degrees
  std::vector<double> rotations;  // alpha: depth directions -> photo directions, rad
  {
    std::vector<double> hd(90, 0.0), hp(90, 0.0);
    for (const auto& s : samples) hd[size_t(Bin90(s.psi))] += 1;
    const double kh = std::min(1.0, 400.0 / std::max(grey.cols, grey.rows));
    const Field f = MakeField(grey, kh, 0);
    for (int y = 0; y < f.P.rows; ++y)
      for (int x = 0; x < f.P.cols; ++x) {
        const cv::Vec2f p = f.P.at<cv::Vec2f>(y, x);
        const double m = std::hypot(p[0], p[1]);
        if (m > 0.5) hp[size_t(Bin90(0.5 * std::atan2(p[1], p[0])))] += m;
      }
    hd = Smooth90(hd), hp = Smooth90(hp);
    std::vector<double> corr(90, 0.0);
    for (int a = 0; a < 90; ++a)
      for (int b = 0; b < 90; ++b) corr[size_t(a)] += hp[size_t((b + a) % 90)] * hd[size_t(b)];
    double mean = 0, best = 0;
    for (double c : corr) mean += c / 90, best = std::max(best, c);
    const double full_step = step;
    if (best < o.min_rotation_peakiness * mean) {
      for (double a = 0; a < 2 * kPi - 1e-9; a += full_step) rotations.push_back(a);
    } else {
      std::vector<int> peaks;
      std::vector<double> c2 = corr;
      for (int k = 0; k < o.rotation_peaks; ++k) {
        const int i = int(std::max_element(c2.begin(), c2.end()) - c2.begin());
        if (c2[size_t(i)] <= mean) break;
        peaks.push_back(i);
        for (int d = -10; d <= 10; ++d) c2[size_t((i + d + 90) % 90)] = 0;
      }
      const double w = o.rotation_window_deg * kPi / 180;
      for (int p : peaks)
        for (int q = 0; q < 4; ++q)
          for (double d = -w; d <= w + 1e-9; d += full_step) rotations.push_back((p + 0.5) * kPi / 180 + q * kPi / 2 + d);
    }
  }

  // ---- coarse search: FFT correlation per (rotation, scale)
  struct Coarse {
    double z, alpha, s;
    int tx, ty;
    double coverage;
  };
  std::vector<Coarse> coarse;
  const int total = int(samples.size());
  const int min_n = std::max(o.min_samples, int(std::ceil(o.min_overlap * total)));
  // templates (and their spectra for the current DFT size), per rotation
  std::vector<cv::Mat> tmpl(rotations.size()), tweight(rotations.size());
  for (size_t r = 0; r < rotations.size(); ++r) {
    const double ca = std::cos(rotations[r]), sa = std::sin(rotations[r]);
    cv::Mat T(Wt, Wt, CV_32FC2, cv::Scalar(0, 0)), W(Wt, Wt, CV_32F, cv::Scalar(0));
    for (const auto& s : samples) {
      const double dx = (s.q.x - qc.x) / cell, dy = (s.q.y - qc.y) / cell;
      const double yx = ca * dx - sa * dy + Rt, yy = sa * dx + ca * dy + Rt;
      const int ix = int(std::floor(yx)), iy = int(std::floor(yy));
      const float fx = float(yx - ix), fy = float(yy - iy);
      const cv::Vec2f v = s.w * cv::Vec2f(float(std::cos(2 * (s.psi + rotations[r]))), float(std::sin(2 * (s.psi + rotations[r]))));
      const float wts[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
      const int xs[4] = {ix, ix + 1, ix, ix + 1}, ys[4] = {iy, iy, iy + 1, iy + 1};
      for (int k = 0; k < 4; ++k) {
        if (xs[k] < 0 || ys[k] < 0 || xs[k] >= Wt || ys[k] >= Wt) continue;
        T.at<cv::Vec2f>(ys[k], xs[k]) += v * wts[k];
        W.at<float>(ys[k], xs[k]) += wts[k] * s.w * s.w;  // the null variance: sum of w^2
      }
    }
    tmpl[r] = T;
    cv::integral(W, tweight[r], CV_64F);
  }
  // the photo's oriented field on a pyramid (unblurred), averaged down to the
  // cells of each scale: edge orientation energy per cell, as the template
  std::vector<Field> pyramid;
  {
    cv::Mat1f g = grey;
    for (int l = 0; l < 8; ++l) {
      pyramid.push_back(MakeField(g, 1.0, 0));
      if (std::min(g.cols, g.rows) < 16) break;
      cv::Mat1f h;
      cv::resize(g, h, cv::Size((g.cols + 1) / 2, (g.rows + 1) / 2), 0, 0, cv::INTER_AREA);
      g = h;
    }
  }
  auto coarse_field = [&](double s) {
    const double k = s / (ps * cell);  // cells per image px
    const int level = std::clamp(int(std::floor(std::log2(1.0 / (3 * k)))), 0, int(pyramid.size()) - 1);
    const cv::Mat& src = pyramid[size_t(level)].P;
    const double kl = k * std::pow(2.0, level);  // cells per level px
    Field f;
    f.k = k;
    cv::resize(src, f.P, cv::Size(std::max(1, int(std::lround(src.cols * kl))), std::max(1, int(std::lround(src.rows * kl)))), 0, 0,
               kl < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
    cv::GaussianBlur(f.P, f.P, cv::Size(), 0.5);
    cv::Mat sq;
    cv::multiply(f.P, f.P, sq);
    const cv::Scalar m = cv::mean(sq);
    f.v = std::max((m[0] + m[1]) / 2, 1e-6);
    return f;
  };
  // Scales in groups that share a DFT size (at most 6: the photo spectra of
  // a group are kept), rotations inside: one template spectrum per rotation
  // and group.
  struct Spec { double s; int Wp, Hp; double v; cv::Mat FP; };
  for (size_t g0 = 0; g0 < scales.size();) {
    std::vector<Spec> group;
    cv::Size N(0, 0);
    size_t g1 = g0;
    for (; g1 < scales.size() && group.size() < 6; ++g1) {
      Field f = coarse_field(scales[g1]);
      const cv::Size n(cv::getOptimalDFTSize(f.P.cols + Wt - 1), cv::getOptimalDFTSize(f.P.rows + Wt - 1));
      if (!group.empty() && n != N) break;
      N = n;
      cv::Mat Pp(N, CV_32FC2, cv::Scalar(0, 0)), FP;
      f.P.copyTo(Pp(cv::Rect(0, 0, f.P.cols, f.P.rows)));
      cv::dft(Pp, FP, cv::DFT_COMPLEX_OUTPUT);
      group.push_back({scales[g1], f.P.cols, f.P.rows, f.v, FP});
    }
    g0 = g1;
    for (size_t r = 0; r < rotations.size(); ++r) {
      cv::Mat Tspec;
      {
        cv::Mat Tp(N, CV_32FC2, cv::Scalar(0, 0));
        tmpl[r].copyTo(Tp(cv::Rect(0, 0, Wt, Wt)));
        cv::dft(Tp, Tspec, cv::DFT_COMPLEX_OUTPUT);
      }
     for (const Spec& sp : group) {
      const double s = sp.s, norm_v = sp.v;
      const int Wp = sp.Wp, Hp = sp.Hp;
      const cv::Mat& FP = sp.FP;
      cv::Mat C;
      cv::mulSpectrums(FP, Tspec, C, 0, true);
      cv::idft(C, C, cv::DFT_SCALE | cv::DFT_COMPLEX_OUTPUT);
      ++res.poses;
      const cv::Mat& I = tweight[r];
      // best translations of this map (up to 3, 3 cells apart)
      Coarse best[3];
      for (auto& b : best) b.z = -1e18;
      for (int cy = 0; cy < N.height; ++cy) {
        const int ty = cy <= Hp - 1 ? cy : cy - N.height;
        if (ty < -(Wt - 1) || ty > Hp - 1) continue;
        const int ya = std::max(0, -ty), yb = std::min(Wt, Hp - ty);
        if (yb <= ya) continue;
        const cv::Vec2f* row = C.ptr<cv::Vec2f>(cy);
        for (int cx = 0; cx < N.width; ++cx) {
          const int tx = cx <= Wp - 1 ? cx : cx - N.width;
          if (tx < -(Wt - 1) || tx > Wp - 1) continue;
          const double v = row[cx][0];
          if (v <= 0) continue;
          const int xa = std::max(0, -tx), xb = std::min(Wt, Wp - tx);
          if (xb <= xa) continue;
          const double n = I.at<double>(yb, xb) - I.at<double>(ya, xb) - I.at<double>(yb, xa) + I.at<double>(ya, xa);
          if (n < min_n) continue;
          const double z = v / std::sqrt(norm_v * n);
          if (z <= best[2].z) continue;
          Coarse c{z, rotations[r], s, tx, ty, n / total};
          // keep 3 separated maxima
          int near = -1;
          for (int b = 0; b < 3; ++b)
            if (best[b].z > -1e17 && std::abs(best[b].tx - tx) <= 3 && std::abs(best[b].ty - ty) <= 3) { near = b; break; }
          if (near >= 0) {
            if (z > best[near].z) best[near] = c;
          } else {
            best[2] = c;
          }
          std::sort(best, best + 3, [](const Coarse& a, const Coarse& b) { return a.z > b.z; });
        }
      }
      for (const auto& b : best)
        if (b.z > -1e17) coarse.push_back(b);
     }
    }
  }
  if (coarse.empty()) return fail("no pose puts enough of the depth outlines inside the photo");
  std::sort(coarse.begin(), coarse.end(), [](const Coarse& a, const Coarse& b) { return a.z > b.z; });

  auto coarse_T = [&](const Coarse& c) {
    const double k = c.s / (ps * cell);
    const cv::Matx33d A1(ps, 0, 0, 0, ps, 0, 0, 0, 1);
    const cv::Matx33d A2(k, 0, 0.5 * k - 0.5, 0, k, 0.5 * k - 0.5, 0, 0, 1);
    const cv::Matx33d A3(1, 0, -double(c.tx) - Rt, 0, 1, -double(c.ty) - Rt, 0, 0, 1);
    const double ca = std::cos(-c.alpha), sa = std::sin(-c.alpha);
    const cv::Matx33d A4(cell * ca, -cell * sa, qc.x, cell * sa, cell * ca, qc.y, 0, 0, 1);
    return cv::Matx33d(A4 * A3 * A2 * A1);
  };

  // ---- fine scoring at photo resolution
  // at most ~6000 samples, of which objects at most 2000 (evenly thinned)
  std::vector<Sample> fs;
  {
    const size_t nb = building_samples, no = samples.size() - nb;
    const size_t keep_o = std::min<size_t>(no, 2000), keep_b = std::min(nb, 6000 - keep_o);
    for (size_t i = 0; i < keep_b; ++i) fs.push_back(samples[i * nb / keep_b]);
    for (size_t i = 0; i < keep_o; ++i) fs.push_back(samples[nb + i * no / keep_o]);
  }
  std::map<std::pair<int, int>, Field> fields;  // per pyramid level and blur
  auto field_for = [&](double s, bool wide = false) -> const Field& {
    // field px <= ~1.5 depth px, never finer than the photo
    const int level = std::clamp(int(std::floor(std::log2(1.5 * ps / s))), 0, int(pyramid.size()) - 1);
    const double px = std::pow(2.0, level) * s / ps;  // depth px per field px
    // the wide blur in powers of 2 (few distinct fields), and at most 3 kept:
    // each is a full-size photo field
    const int blur10 = wide ? 10 << std::clamp(int(std::lround(std::log2(std::max(1.0, 0.5 * cell / px)))), 0, 4) : 10;
    auto it = fields.find({level, blur10});
    if (it == fields.end()) {
      if (fields.size() >= 3) fields.clear();
      Field f;
      f.k = std::pow(0.5, level);
      cv::GaussianBlur(pyramid[size_t(level)].P, f.P, cv::Size(), blur10 / 10.0);
      cv::Mat sq;
      cv::multiply(f.P, f.P, sq);
      const cv::Scalar m = cv::mean(sq);
      f.v = std::max((m[0] + m[1]) / 2, 1e-6);
      it = fields.emplace(std::make_pair(level, blur10), std::move(f)).first;
    }
    return it->second;
  };
  // One sample's score m cos 2(phi - psi) at the pose whose inverse is D
  // (false when it falls outside the field).
  auto sample_score = [&](const Field& f, const cv::Matx33d& D, const Sample& s, double* score) {
    const cv::Point2d p = Map(D, s.q), pn = Map(D, cv::Point2d(s.q) + cv::Point2d(s.n));
    // bounds on the float coordinates At2 gets: a double just below w - 1
    // rounds to w - 1 as a float, and its bilinear cell reads past the field
    const float ux = float((p.x * ps + 0.5) * f.k - 0.5), uy = float((p.y * ps + 0.5) * f.k - 0.5);
    if (!(ux >= 0 && uy >= 0 && ux < float(f.P.cols - 1) && uy < float(f.P.rows - 1))) return false;
    // the mapped normal's doubled angle 2a without trigonometry:
    // cos 2a = (x^2 - y^2) / r^2, sin 2a = 2xy / r^2
    const double nx = pn.x - p.x, ny = pn.y - p.y, r2 = nx * nx + ny * ny;
    if (!(r2 > 0)) return false;
    const cv::Vec2f v = At2(f.P, ux, uy);
    *score = (v[0] * (nx * nx - ny * ny) + v[1] * 2 * nx * ny) / r2;
    return true;
  };
  // (-1e18 below the overlap floor, unless `floor` is false)
  auto fine_score = [&](const cv::Matx33d& T, const Field& f, double* coverage, bool floor = true) {
    const cv::Matx33d D = T.inv();
    double sum = 0, w2 = 0, v = 0;
    int n = 0;
    for (const auto& s : fs) {
      if (!sample_score(f, D, s, &v)) continue;
      sum += s.w * v;
      w2 += double(s.w) * s.w;
      ++n;
    }
    if (coverage) *coverage = double(n) / double(fs.size());
    const int need = std::max(o.min_samples, int(std::ceil(o.min_overlap * double(fs.size()))));
    if (n >= need) return sum / std::sqrt(f.v * w2);
    return floor || !(w2 > 0) ? -1e18 : sum / std::sqrt(f.v * w2);
  };
  auto refine = [&](cv::Matx33d T, double s, double start_px) {
   double best = 0;
   for (int stage = 0; stage < 2; ++stage) {
    const Field& f = field_for(s, stage == 0);
    best = fine_score(T, f, nullptr);
    double tstep = stage == 0 ? start_px : 1.0, rstep = stage == 0 ? step / 2 : step / 8, sstep = rstep;
    const double last = stage == 0 ? 0.5 : 0.15;
    // rotation and scale about the outline centre in view
    for (int guard = 0; guard < 300 && tstep > last; ++guard) {
      bool improved = false;
      for (int k = 0; k < 4; ++k)
        for (double sg : {1.0, -1.0}) {
          cv::Matx33d C = cv::Matx33d::eye();
          if (k == 0) C(0, 2) = sg * tstep;
          else if (k == 1) C(1, 2) = sg * tstep;
          else {
            const double a = k == 2 ? sg * rstep : 0, l = k == 3 ? std::exp(sg * sstep) : 1;
            const double ca = l * std::cos(a), sa = l * std::sin(a);
            C = cv::Matx33d(ca, -sa, qc.x - ca * qc.x + sa * qc.y, sa, ca, qc.y - sa * qc.x - ca * qc.y, 0, 0, 1);
          }
          const cv::Matx33d Tn = C * T;
          const double v = fine_score(Tn, f, nullptr);
          if (v > best + 1e-9) best = v, T = Tn, improved = true;
        }
      if (!improved) tstep *= 0.5, rstep *= 0.5, sstep *= 0.5;
    }
   }
    return Pose{T, best, 0};
  };

  // Completeness (OutlineSearchOptions::completeness_power): the share of
  // the building outlines' arcs (8 consecutive samples of one outline, all
  // in view) whose summed score is positive.
  auto completeness = [&](const cv::Matx33d& T) {
    const double sc = std::sqrt(std::abs(T(0, 0) * T(1, 1) - T(0, 1) * T(1, 0)));
    const Field& f = field_for(sc);
    const cv::Matx33d D = T.inv();
    int good = 0, all = 0;
    for (size_t i = 0; i < building_samples;) {
      const int b = samples[i].b;
      double sum = 0, v = 0;
      int n = 0;
      size_t j = i;
      for (; j < building_samples && j < i + 8 && samples[j].b == b; ++j)
        if (sample_score(f, D, samples[j], &v)) sum += v, ++n;
      if (n == 8) ++all, good += sum > 0;
      i = j;
    }
    return all ? double(good) / all : 0.0;
  };
  auto weigh = [&](Pose p) {
    if (o.completeness_power > 0 && p.z > 0) p.z *= std::pow(completeness(p.T), o.completeness_power);
    return p;
  };
  std::vector<Pose> refined;
  std::vector<cv::Matx33d> seeds;
  for (const Coarse& c : coarse) {
    if (int(seeds.size()) >= o.coarse_candidates) break;
    const cv::Matx33d T = coarse_T(c);
    bool distinct = true;
    for (const auto& sd : seeds) distinct = distinct && PoseDistance(sd, T, probe) > 2 * cell;
    if (!distinct) continue;
    seeds.push_back(T);
    refined.push_back(weigh(refine(T, c.s, 0.5 * cell)));
  }
  std::sort(refined.begin(), refined.end(), [](const Pose& a, const Pose& b) { return a.z > b.z; });
  const size_t bi = 0;
  Pose best = refined[bi];
  // Poses are told apart where the photo is: over the outline samples the
  // best pose puts in view (every 4th). The tile's corners (`probe`) lie far
  // outside a photo of part of the tile, where a small rotation or scale
  // about the photo's outlines is magnified: the same answer counted as its
  // own runner-up, and a perspective refinement that moved the outlines
  // 2-4 px looked like 11-14 px (issue 21).
  std::vector<cv::Point2d> view_probe;
  {
    const double pw = photo.cols / ps, ph = photo.rows / ps;
    const cv::Matx33d D = best.T.inv();
    for (size_t i = 0; i < samples.size(); i += 4) {
      const cv::Point2d p = Map(D, samples[i].q);
      if (p.x >= 0 && p.y >= 0 && p.x < pw && p.y < ph) view_probe.emplace_back(samples[i].q);
    }
    if (view_probe.size() < probe.size()) view_probe = probe;
  }
  double runner = 0;
  for (size_t i = 0; i < refined.size(); ++i)
    if (i != bi && PoseDistance(best.T, refined[i].T, view_probe) > o.distinct_px) runner = std::max(runner, refined[i].z);

  // final refinement on the image check, which also gives its verdict
  std::string model = "similarity";
  bool overlap_lost = false;  // the refined pose keeps less than min_overlap of the template in view
  double moved = 0;  // by the image check's refinement (depth px)
  if (evidence) {
    const cv::Matx33d T2 = evidence->Refine(best.T, o.perspective);
    moved = PoseDistance(best.T, T2, view_probe);
    if (moved < o.distinct_px) {
      best.T = T2;
      if (o.perspective) model = "perspective";
    }
    res.edge = evidence->Evaluate(best.T);
  }
  {
    const cv::Matx33d& T = best.T;
    const double s = std::sqrt(std::abs(T(0, 0) * T(1, 1) - T(0, 1) * T(1, 0)));
    best.z = fine_score(best.T, field_for(s), &best.coverage);
    // The image check's refinement can leave just under min_overlap of the
    // template in view: no answer, reported with its score and the reason
    // (not a score of -1e18).
    if (best.z <= -1e17) overlap_lost = true, best.z = fine_score(best.T, field_for(s), nullptr, false);
    res.completeness = completeness(best.T);
    if (o.completeness_power > 0 && best.z > 0) best.z *= std::pow(res.completeness, o.completeness_power);
  }
  res.photo_to_depth = best.T;
  // The photo's lean (edge_evidence.h): the scores above are of the pose
  // that puts the roofs on edges; the answer maps the ground.
  if (evidence && evidence->Accepts(res.edge)) {  // never what makes an answer pass
    cv::Point2d lean;
    const cv::Matx33d T3 = evidence->Refine(best.T, o.perspective, true, nullptr, &lean);
    if (lean != cv::Point2d() && PoseDistance(best.T, T3, view_probe) < o.distinct_px) {
      const EdgeScore e = evidence->Evaluate(T3, lean);
      if (evidence->Accepts(e) && e.regions_on_edges >= res.edge.regions_on_edges)
        res.photo_to_depth = T3, res.lean_px_per_m = lean, res.edge = e;
    }
  }
  res.model = model;
  res.score = best.z;
  res.runner_up = runner;
  res.coverage = best.coverage;
  // confidence: the margin of the best over the best clearly different pose
  const double margin = best.z > 0 && !overlap_lost ? (best.z - std::max(runner, 0.0)) / best.z : 0.0;
  res.confidence = std::clamp(margin / 0.5, 0.0, 1.0);
  // outlines in view: a single building's outline can sit on any similar
  // rectangle of other ground
  {
    const cv::Matx33d D = best.T.inv();
    std::vector<int> per(outlines.size(), 0);
    for (const auto& smp : samples) {
      if (smp.b < 0) continue;
      const cv::Point2d p = Map(D, smp.q);
      const double u = p.x * ps, v = p.y * ps;
      if (u >= 0 && v >= 0 && u < grey.cols && v < grey.rows) ++per[size_t(smp.b)];
    }
    for (int c : per) res.outlines_in_view += c >= 10;
  }
  // The image check must see min_outlines outlines too: it samples them
  // more sparsely than the search (EdgeEvidenceOptions::step_px, and
  // min_region_points per outline), and seed 136's 34 x 42 px photo passed
  // with 2 outlines in view for the search, 1 for the check (a lone roof on
  // edges at contrast 5.5), 52.6 px off.
  const bool edge_ok = !evidence || (evidence->Accepts(res.edge) && res.edge.regions >= o.min_outlines &&
                                     res.edge.regions_on_edges >= o.min_on_edges * res.edge.regions);
  // Held under the perspective refinement: on 1000 x 1000 tiles (photos with
  // up to 0.1 of perspective) the similarities it moved >= distinct_px were
  // 3.3-8.6 px from the truth (issue 21, docs/aerial.md); no small-tile
  // answer of seeds 108-111 changed.
  const bool held = !evidence || !o.perspective || moved < o.distinct_px;
  res.held = held;
  const bool complete = res.completeness >= o.min_completeness;
  res.ok = res.confidence >= o.min_confidence && edge_ok && res.outlines_in_view >= o.min_outlines && held && complete;
  res.reason = cv::format("outline search: score %.1f, runner-up %.1f, confidence %.2f, coverage %.2f, completeness %.2f, "
                          "%d outlines in view, %d poses",
                          best.z, runner, res.confidence, best.coverage, res.completeness, res.outlines_in_view, res.poses);
  if (evidence && res.edge.enough)
    res.reason += cv::format(", outline edge contrast %.2f, %d of %d outlines on edges", res.edge.contrast,
                             res.edge.regions_on_edges, res.edge.regions);
  if (evidence && res.edge.enough && res.edge.regions < o.min_outlines)
    res.reason += cv::format(", fewer than %d outlines in view for the image check", o.min_outlines);
  if (!held)
    res.reason += cv::format(", the image check's perspective refinement moves it %.1f px (>= %.0f): not the pose",
                             moved, o.distinct_px);
  if (!complete)
    res.reason += cv::format(", only %.2f of its outlines' arcs in view on edges (%.2f needed): parts of outlines "
                             "on other ground's edges",
                             res.completeness, o.min_completeness);
  if (overlap_lost)
    res.reason += cv::format(", refined, only %.2f of its outline samples fall in the photo (floor %.2f, or %d "
                             "samples): confidence 0",
                             best.coverage, o.min_overlap, o.min_samples);
  if (!res.ok) res.reason = "no registration found: " + res.reason;
  res.ms = timer.ElapsedMs();
  return res;
}

}  // namespace mvkp
