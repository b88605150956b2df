#include "mvkp/ortho/optical_regions.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/ortho/internal/colour_canny.h"

namespace mvkp {

void OpticalSegmentOptions::Check() const {
  auto req = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, std::string("optical segmentation: ") + m); };
  req(pre_blur_sigma >= 0 && pre_blur_sigma <= 10, "pre_blur_sigma must be in [0, 10]");
  req(canny_low >= 0 && canny_high >= canny_low, "need 0 <= canny_low <= canny_high");
  req(edge_probe >= 1 && edge_probe <= 10, "edge_probe must be in [1, 10]");
  req(seed_cell >= 2, "seed_cell must be >= 2");
  req(thin_suppress >= 0 && thin_suppress <= 15, "thin_suppress must be in [0, 15]");
  req(ofe_ratio >= 0, "ofe_ratio must be >= 0");
  req(range_tolerance >= 0 && range_tolerance_strict >= 0 && range_soft_max >= 0, "range tolerances must be >= 0");
  req(range_len >= 1, "range_len must be >= 1");
  req(min_area >= 1, "min_area must be >= 1");
  req(max_area_fraction > 0 && max_area_fraction <= 1, "max_area_fraction must be in (0, 1]");
  req(max_upp >= 0 && upp_scale > 0, "need max_upp >= 0 and upp_scale > 0");
  req(merge_gap >= 0 && merge_gap <= 5, "merge_gap must be in [0, 5]");
  req(barrier_dilate >= 0 && barrier_dilate <= 3, "barrier_dilate must be in [0, 3]");
  req(contour_dilate >= 0 && contour_dilate <= 5, "contour_dilate must be in [0, 5]");
  req(max_elongation >= 1 && max_elongation_unshaded >= 1 && min_solidity >= 0 && min_solidity <= 1, "bad elongation / solidity limits");
  req(!fbm.Valid() || fbm.window <= 31, "fbm.window must be <= 31");
}

namespace {

enum : uint8_t { kNoEdge = 0, kTrueEdge = 1, kInRegionEdge = 2 };

struct Maps {
  cv::Mat3b img;       // smoothed, selectively smoothed photo
  cv::Mat1b gray;      // intensity of img
  cv::Mat1b raw_gray;  // unsmoothed intensity (fractal error)
  cv::Mat1b veg, shadow, edge, pref;
  cv::Mat1b barrier;   // true edges (optionally dilated)
};

cv::Mat3b ToBgr(const cv::Mat& in) {
  Require(!in.empty(), ErrorCode::kBadImage, "optical segmentation: empty image");
  Require(in.depth() == CV_8U && (in.channels() == 1 || in.channels() == 3 || in.channels() == 4),
          ErrorCode::kBadImage, "optical segmentation: need an 8-bit grey, BGR or BGRA image");
  cv::Mat3b out;
  if (in.channels() == 1) cv::cvtColor(in, out, cv::COLOR_GRAY2BGR);
  else if (in.channels() == 4) cv::cvtColor(in, out, cv::COLOR_BGRA2BGR);
  else out = in;
  return out;
}

Maps BuildMaps(const cv::Mat3b& bgr, const OpticalSegmentOptions& o) {
  Maps m;
  cv::cvtColor(bgr, m.raw_gray, cv::COLOR_BGR2GRAY);
  if (o.pre_blur_sigma > 0) cv::GaussianBlur(bgr, m.img, cv::Size(), o.pre_blur_sigma);
  else m.img = bgr.clone();
  if (o.thin_suppress >= 2) {
    const cv::Mat k = cv::getStructuringElement(cv::MORPH_RECT, {o.thin_suppress, o.thin_suppress});
    cv::morphologyEx(m.img, m.img, cv::MORPH_OPEN, k);
    cv::morphologyEx(m.img, m.img, cv::MORPH_CLOSE, k);
  }
  cv::cvtColor(m.img, m.gray, cv::COLOR_BGR2GRAY);
  const int rows = bgr.rows, cols = bgr.cols;

  // Vegetation and shadow maps.
  m.veg.create(bgr.size());
  m.shadow.create(bgr.size());
  for (int y = 0; y < rows; ++y) {
    const cv::Vec3b* p = m.img[y];
    const uint8_t* g = m.gray[y];
    uint8_t *v = m.veg[y], *s = m.shadow[y];
    for (int x = 0; x < cols; ++x) {
      const int B = p[x][0], G = p[x][1], R = p[x][2];
      const int exg = 2 * G - R - B;
      v[x] = (G >= R + o.veg_green_margin && G + 2 >= B && exg >= o.veg_exg &&
              exg >= o.veg_exg_rel * (B + G + R + 1)) ? 255 : 0;
      s[x] = (g[x] < o.shadow_intensity && std::max({B, G, R}) < o.shadow_channel) ? 255 : 0;
    }
  }
  cv::morphologyEx(m.veg, m.veg, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));

  // Edge map: Canny on the smoothed colour photo (max gradient over channels).
  cv::Mat1b canny;
  internal::ColourCanny(m.img, &canny, o.canny_low, o.canny_high, true);
  m.edge = cv::Mat1b(bgr.size(), kNoEdge);
  cv::Mat3b hsv;
  cv::Mat1s gx, gy;
  if (o.split_edges) {
    cv::cvtColor(m.img, hsv, cv::COLOR_BGR2HSV);
    cv::Sobel(m.gray, gx, CV_16S, 1, 0);
    cv::Sobel(m.gray, gy, CV_16S, 0, 1);
  }
  auto similar = [&](cv::Point a, cv::Point b) {
    const cv::Vec3b ha = hsv(a), hb = hsv(b);
    const bool sa = ha[1] >= o.sat_min_for_hue, sb = hb[1] >= o.sat_min_for_hue;
    if (sa && sb) {
      int d = std::abs(int(ha[0]) - int(hb[0]));
      d = std::min(d, 180 - d);
      return d <= o.hue_similar;
    }
    if (!sa && !sb) return std::abs(int(m.gray(a)) - int(m.gray(b))) <= o.gray_similar;
    return false;
  };
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      if (!canny(y, x)) continue;
      uint8_t kind = kTrueEdge;
      if (o.split_edges) {
        const bool horiz = std::abs(gx(y, x)) >= std::abs(gy(y, x));
        const cv::Point d = horiz ? cv::Point(1, 0) : cv::Point(0, 1), p(x, y);
        cv::Point a(-1, -1), b(-1, -1);
        for (int k = 1; k <= o.edge_probe; ++k) {
          const cv::Point q = p - k * d;
          if (q.x < 0 || q.y < 0) break;
          if (!canny(q)) { a = q; break; }
        }
        for (int k = 1; k <= o.edge_probe; ++k) {
          const cv::Point q = p + k * d;
          if (q.x >= cols || q.y >= rows) break;
          if (!canny(q)) { b = q; break; }
        }
        if (a.x >= 0 && b.x >= 0 && similar(a, b)) kind = kInRegionEdge;
      }
      m.edge(y, x) = kind;
    }

  // The edge classification's working maps go before the smoothing copies the photo.
  canny.release();
  hsv.release();
  gx.release();
  gy.release();

  // Selective smoothing of in-region edge pixels.
  if (o.split_edges && o.selective_smoothing) {
    const cv::Mat3b src = m.img.clone();
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < cols; ++x) {
        if (m.edge(y, x) != kInRegionEdge) continue;
        int n = 0, sb = 0, sg = 0, sr = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int yy = y + dy, xx = x + dx;
            if ((dx == 0 && dy == 0) || yy < 0 || xx < 0 || yy >= rows || xx >= cols) continue;
            if (m.edge(yy, xx) != kNoEdge) continue;
            const cv::Vec3b c = src(yy, xx);
            sb += c[0]; sg += c[1]; sr += c[2]; ++n;
          }
        if (n == 0) continue;
        const cv::Vec3b c((sb + n / 2) / n, (sg + n / 2) / n, (sr + n / 2) / n);
        m.img(y, x) = c;
        m.gray(y, x) = cv::saturate_cast<uint8_t>(0.114 * c[0] + 0.587 * c[1] + 0.299 * c[2]);
      }
  }

  // Colour preference: 1 + index of a channel exceeding both others by the margin.
  m.pref.create(bgr.size());
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      const cv::Vec3b c = m.img(y, x);
      uint8_t p = 0;
      for (int ch = 0; ch < 3; ++ch)
        if (c[ch] >= c[(ch + 1) % 3] + o.color_margin && c[ch] >= c[(ch + 2) % 3] + o.color_margin) p = uint8_t(ch + 1);
      m.pref(y, x) = p;
    }

  m.barrier = (m.edge == kTrueEdge);
  if (o.barrier_dilate > 0)
    cv::dilate(m.barrier, m.barrier,
               cv::getStructuringElement(cv::MORPH_RECT, {2 * o.barrier_dilate + 1, 2 * o.barrier_dilate + 1}));
  return m;
}

struct Segment {
  int area = 0;
  int lo = 0, hi = 0;      // dynamic intensity range
  double irep = 0;         // in-region edge pixels (weighted)
  int pref = 0;            // colour preference of the seed
  double sum[3] = {0, 0, 0};
  cv::Rect box;
  double Uct(int range_len) const { return (1.0 + double(hi - lo) / range_len) * irep; }
};

struct UnionFind {
  std::vector<int> p;
  explicit UnionFind(int n) : p(n) { std::iota(p.begin(), p.end(), 0); }
  int Find(int a) { return p[a] == a ? a : p[a] = Find(p[a]); }
  void Unite(int a, int b) { p[Find(a)] = Find(b); }
};

// Makes a contour counter-clockwise on screen (negative shoelace sum in image
// coordinates) starting at its smallest-y (then smallest-x) point.
void Normalise(std::vector<cv::Point>& c) {
  double s = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    const cv::Point a = c[i], b = c[(i + 1) % c.size()];
    s += double(a.x) * b.y - double(b.x) * a.y;
  }
  if (s > 0) std::reverse(c.begin(), c.end());
  auto first = std::min_element(c.begin(), c.end(), [](cv::Point a, cv::Point b) {
    return a.y != b.y ? a.y < b.y : a.x < b.x;
  });
  std::rotate(c.begin(), first, c.end());
}

// Fraction of the outline's length (polygonised with tolerance eps) whose
// direction lies within 10 degrees (mod 90) of the length-weighted dominant
// direction: ~1 for rectilinear buildings, low for natural blobs.
double Rectilinearity(const std::vector<cv::Point>& c, double eps) {
  std::vector<cv::Point> poly;
  cv::approxPolyDP(c, poly, eps, true);
  if (poly.size() < 3) return 0;
  constexpr int kBins = 90;
  double hist[kBins] = {0}, total = 0;
  std::vector<std::pair<double, double>> seg;  // (angle mod 90 in degrees, length)
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point d = poly[(i + 1) % poly.size()] - poly[i];
    const double len = std::hypot(d.x, d.y);
    if (len <= 0) continue;
    double a = std::atan2(double(d.y), double(d.x)) * 180 / CV_PI;
    a = std::fmod(a + 360.0, 90.0);
    seg.emplace_back(a, len);
    total += len;
    hist[std::min(kBins - 1, int(a))] += len;
  }
  if (total <= 0) return 0;
  double best = -1, best_a = 0;
  for (int b = 0; b < kBins; ++b) {
    double s = 0;
    for (int k = -10; k <= 10; ++k) s += hist[(b + k + kBins) % kBins];
    if (s > best) best = s, best_a = b + 0.5;
  }
  double in = 0;
  for (auto& [a, len] : seg) {
    double d = std::abs(a - best_a);
    d = std::min(d, 90 - d);
    if (d <= 10) in += len;
  }
  return in / total;
}

// `bgr` is released once the maps are built (the maps hold what is needed).
std::vector<PhotoRegion> SegmentBgr(cv::Mat3b bgr, const OpticalSegmentOptions& opt, cv::Mat1i* labels_out) {
  const int rows = bgr.rows, cols = bgr.cols;
  const cv::Size size = bgr.size();
  Maps m = BuildMaps(bgr, opt);
  bgr.release();

  // fBm model: given, or fitted on this photo's (eroded) vegetation map.
  FbmModel fbm = opt.fbm;
  bool use_fractal = opt.use_fractal;
  std::vector<cv::Mat1f> fitted_ofe;  // the fit's OFE map of this photo, reused below
  if (use_fractal && !fbm.Valid()) {
    cv::Mat1b natural;
    cv::erode(m.veg, natural, cv::getStructuringElement(cv::MORPH_RECT, {5, 5}));
    try {
      fbm = FitFbm({m.raw_gray}, {natural}, 7, 3, &fitted_ofe);
    } catch (const Error&) {
      use_fractal = false;  // too little known-natural texture to fit on
    }
  }
  // The fractal-error test as a mask (1 byte a pixel instead of the float map).
  cv::Mat1b textured;  // 255: fractal error below the building threshold (natural texture)
  if (use_fractal) {
    const float ofe_min = static_cast<float>(opt.ofe_ratio * fbm.ofe);
    textured = (fitted_ofe.empty() ? OverallFractalError(m.raw_gray, fbm) : fitted_ofe[0]) < ofe_min;
    fitted_ofe.clear();
  }

  // label: the segment id per pixel. tested: 1 where the growing segment has
  // already looked (reset from `touched` after each segment), instead of a
  // second int map of ids.
  cv::Mat1i label(size, 0);
  cv::Mat1b tested(size, uchar(0));
  // pixels as y * cols + x (4 bytes, not a cv::Point's 8: a segment of the
  // open ground queues and touches most of the photo)
  Require(double(rows) * cols < 2147483647.0, ErrorCode::kInvalidArgument, "SegmentOptical: image too large");
  std::vector<int> touched;
  std::vector<Segment> segs(1);  // index 0 unused
  std::vector<int> queue;
  queue.reserve(4096);

  auto seed_ok = [&](int y, int x) {
    if (label(y, x) || m.edge(y, x) != kNoEdge) return false;
    if (opt.use_vegetation && m.veg(y, x)) return false;
    if (opt.use_shadow && m.shadow(y, x)) return false;
    if (use_fractal && textured(y, x)) return false;
    return true;
  };

  auto grow = [&](int sy, int sx) {
    const int id = static_cast<int>(segs.size());
    Segment s;
    s.lo = s.hi = m.gray(sy, sx);
    s.pref = m.pref(sy, sx);
    s.box = cv::Rect(sx, sy, 1, 1);
    int x0 = sx, x1 = sx, y0 = sy, y1 = sy;
    queue.clear();
    queue.push_back(sy * cols + sx);
    label(sy, sx) = id;
    touched.clear();
    touched.push_back(sy * cols + sx);
    tested(sy, sx) = 1;
    static const int dxs[4] = {1, -1, 0, 0}, dys[4] = {0, 0, 1, -1};
    for (size_t qi = 0; qi < queue.size(); ++qi) {
      const cv::Point p(queue[qi] % cols, queue[qi] / cols);
      const cv::Vec3b c = m.img(p);
      s.area += 1;
      s.sum[0] += c[0]; s.sum[1] += c[1]; s.sum[2] += c[2];  // (the seed's colour before its neighbours are tested)
      if (m.edge(p) == kInRegionEdge) s.irep += opt.irep_penalty;
      x0 = std::min(x0, p.x); x1 = std::max(x1, p.x); y0 = std::min(y0, p.y); y1 = std::max(y1, p.y);
      for (int k = 0; k < 4; ++k) {
        const int x = p.x + dxs[k], y = p.y + dys[k];
        if (x < 0 || y < 0 || x >= cols || y >= rows) continue;
        uchar& t = tested(y, x);
        if (t || label(y, x)) continue;
        t = 1;
        touched.push_back(y * cols + x);
        if (m.barrier(y, x)) continue;  // true edge: neither accepted nor expanded
        if (opt.use_vegetation && m.veg(y, x)) continue;
        if (opt.use_shadow && m.shadow(y, x)) continue;
        const int I = m.gray(y, x);
        const int pp = m.pref(y, x);
        if (pp != 0 && s.pref != 0 && pp != s.pref) continue;  // opposite colour preference
        if (I < s.lo || I > s.hi) {
          double t = (pp != s.pref) ? opt.range_tolerance_strict : opt.range_tolerance;
          if (s.area < opt.min_area) t += (1.0 - std::exp(-double(s.area) / opt.min_area)) * opt.range_soft_max;
          if (I < s.lo - t || I > s.hi + t) continue;
          if (std::max(s.hi, I) - std::min(s.lo, I) > opt.range_len) continue;
        }
        if (opt.max_chroma_step > 0) {  // chromaticity close to the region's mean
          const cv::Vec3b c = m.img(y, x);
          const double tc = c[0] + c[1] + c[2] + 1e-9, ts = s.sum[0] + s.sum[1] + s.sum[2] + 1e-9;
          double d = 0;
          for (int ch = 0; ch < 3; ++ch) d += std::abs(c[ch] / tc - s.sum[ch] / ts);
          if (d > opt.max_chroma_step) continue;
        }
        if (use_fractal && textured(y, x)) continue;
        s.lo = std::min(s.lo, I);
        s.hi = std::max(s.hi, I);
        label(y, x) = id;
        queue.push_back(y * cols + x);
      }
    }
    s.box = cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
    segs.push_back(s);
    uchar* const t0 = tested.ptr<uchar>(0);  // continuous: allocated here
    for (const int q : touched) t0[q] = 0;
  };

  // Grid seeds with four-way subdivision.
  const int cell = opt.seed_cell;
  for (int cy = 0; cy < rows; cy += cell)
    for (int cx = 0; cx < cols; cx += cell) {
      const int h = std::min(cell, rows - cy), w = std::min(cell, cols - cx);
      const int y = cy + h / 2, x = cx + w / 2;
      if (seed_ok(y, x)) {
        grow(y, x);
        continue;
      }
      for (int sy = 0; sy < 2; ++sy)
        for (int sx = 0; sx < 2; ++sx) {
          const int yy = std::min(rows - 1, cy + h / 4 + sy * (h / 2));
          const int xx = std::min(cols - 1, cx + w / 4 + sx * (w / 2));
          if (seed_ok(yy, xx)) grow(yy, xx);
        }
    }

  // Candidates: size and uncertainty per pixel.
  const int n = static_cast<int>(segs.size());
  const double max_area = opt.max_area_fraction * rows * cols;
  std::vector<char> cand(n, 0);
  for (int i = 1; i < n; ++i) {
    const Segment& s = segs[i];
    const double upp = s.Uct(opt.range_len) / std::max(1, s.area);
    cand[i] = s.area >= opt.min_area && s.area <= max_area && upp <= opt.max_upp;
  }

  // Region merging.
  UnionFind uf(n);
  if (opt.merge) {
    struct Contact { int total = 0, edge = 0; };
    std::unordered_map<uint64_t, Contact> contacts;
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < cols; ++x) {
        const int a = label(y, x);
        if (!a || !cand[a]) continue;
        for (int dir = 0; dir < 2; ++dir) {
          bool crossed_edge = false;
          for (int j = 1; j <= opt.merge_gap + 1; ++j) {
            const int xx = dir == 0 ? x + j : x, yy = dir == 0 ? y : y + j;
            if (xx >= cols || yy >= rows) break;
            const int b = label(yy, xx);
            if (b == a) break;
            if (b) {
              if (cand[b]) {
                auto& c = contacts[(uint64_t(std::min(a, b)) << 32) | uint32_t(std::max(a, b))];
                c.total += 1;
                c.edge += crossed_edge;
              }
              break;
            }
            crossed_edge |= m.edge(yy, xx) == kTrueEdge;
          }
        }
      }
    for (auto& [key, c] : contacts) {
      const int a = int(key >> 32), b = int(key & 0xffffffffu);
      const Segment &sa = segs[a], &sb = segs[b];
      if (sa.pref != 0 && sb.pref != 0 && sa.pref != sb.pref) continue;
      if (c.total < opt.merge_min_contact * std::sqrt(double(std::min(sa.area, sb.area)))) continue;
      if (c.edge > opt.merge_max_true_edge * c.total) continue;
      const double ta = sa.sum[0] + sa.sum[1] + sa.sum[2] + 1e-9, tb = sb.sum[0] + sb.sum[1] + sb.sum[2] + 1e-9;
      double chroma = 0;
      for (int ch = 0; ch < 3; ++ch) chroma += std::abs(sa.sum[ch] / ta - sb.sum[ch] / tb);
      if (chroma > opt.merge_max_chroma) continue;
      uf.Unite(a, b);
    }
  }

  // Groups -> contours, then regulation.
  std::unordered_map<int, std::vector<int>> groups;
  for (int i = 1; i < n; ++i)
    if (cand[i]) groups[uf.Find(i)].push_back(i);
  const RegionLda lda = opt.lda.Valid() ? opt.lda : DefaultRegionLda();
  std::vector<PhotoRegion> out;
  std::vector<int> root_of(n, 0);
  for (int i = 1; i < n; ++i) root_of[i] = cand[i] ? uf.Find(i) : 0;
  for (auto& [root, parts] : groups) {
    cv::Rect box = segs[parts[0]].box;
    double area = 0, uct = 0;
    for (int i : parts) {
      box |= segs[i].box;
      area += segs[i].area;
      uct += segs[i].Uct(opt.range_len);
    }
    if (area > max_area) continue;
    const int pad = opt.contour_dilate + opt.merge_gap + 2;
    const cv::Rect roi = cv::Rect(box.x - pad, box.y - pad, box.width + 2 * pad, box.height + 2 * pad) &
                         cv::Rect(0, 0, cols, rows);
    cv::Mat1b mask(roi.size(), 0);
    for (int y = 0; y < roi.height; ++y) {
      const int* l = label[roi.y + y] + roi.x;
      uint8_t* mk = mask[y];
      for (int x = 0; x < roi.width; ++x)
        if (l[x] && root_of[l[x]] == root) mk[x] = 255;
    }
    if (parts.size() > 1 && opt.merge_gap > 0) {
      const int k = 2 * opt.merge_gap + 1;
      cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, cv::getStructuringElement(cv::MORPH_RECT, {k, k}));
    }
    if (opt.contour_dilate > 0) {
      const int k = 2 * opt.contour_dilate + 1;
      cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, {k, k}));
    }
    // Cast-shadow evidence: fraction of the outer ring darker than a fraction of its median.
    double dark_ring = 1;
    if (opt.min_shadow_ring > 0 || (opt.regulate && opt.max_elongation_unshaded < opt.max_elongation)) {
      cv::Mat1b ring;
      cv::dilate(mask, ring, cv::getStructuringElement(cv::MORPH_ELLIPSE, {11, 11}));
      ring &= ~mask;
      std::vector<uint8_t> vals;
      for (int y = 0; y < roi.height; ++y)
        for (int x = 0; x < roi.width; ++x)
          if (ring(y, x)) vals.push_back(m.gray(roi.y + y, roi.x + x));
      dark_ring = 0;
      if (!vals.empty()) {
        std::nth_element(vals.begin(), vals.begin() + vals.size() / 2, vals.end());
        const double thr = opt.shadow_ring_ratio * vals[vals.size() / 2];
        size_t dark = 0;
        for (uint8_t v : vals) dark += v < thr;
        dark_ring = double(dark) / vals.size();
      }
      if (dark_ring < opt.min_shadow_ring) continue;
    }
    std::vector<std::vector<cv::Point>> cs;
    cv::findContours(mask, cs, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, roi.tl());
    if (cs.empty()) continue;
    auto& ct = *std::max_element(cs.begin(), cs.end(), [](auto& a, auto& b) {
      return cv::contourArea(a) < cv::contourArea(b);
    });
    PhotoRegion r;
    r.area = cv::contourArea(ct);
    if (r.area < opt.min_area) continue;
    if (opt.regulate) {
      const cv::RotatedRect rr = cv::minAreaRect(ct);
      const double lo = std::max(1.0f, std::min(rr.size.width, rr.size.height));
      const double hi = std::max(rr.size.width, rr.size.height);
      std::vector<cv::Point> hull;
      cv::convexHull(ct, hull);
      r.lda_score = lda.Score(ContourPnr(ct));
      if (hi / lo > opt.max_elongation) continue;
      if (hi / lo > opt.max_elongation_unshaded && dark_ring < opt.shadow_ring_evidence) continue;
      if (r.area < opt.min_solidity * cv::contourArea(hull)) continue;
      if (opt.min_rectilinear > 0 && Rectilinearity(ct, std::max(1.5, 0.02 * std::sqrt(r.area))) < opt.min_rectilinear)
        continue;
      // An outline cut by the photo border says less about the building's
      // shape: a laxer margin for those.
      int on_border = 0;
      for (const cv::Point& q : ct) on_border += q.x == 0 || q.y == 0 || q.x == cols - 1 || q.y == rows - 1;
      const double margin = opt.lda_margin - (on_border >= 0.05 * ct.size() ? opt.lda_border_relax : 0.0);
      if (r.lda_score <= margin) continue;
    } else {
      r.lda_score = lda.Score(ContourPnr(ct));
    }
    r.upp = uct / std::max(1.0, area);
    r.confidence = std::exp(-r.upp / opt.upp_scale);
    r.color_preference = segs[parts[0]].pref;
    Normalise(ct);
    r.contour = std::move(ct);
    r.bbox = cv::boundingRect(r.contour);
    out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(), [](const PhotoRegion& a, const PhotoRegion& b) {
    if (a.confidence != b.confidence) return a.confidence > b.confidence;
    return a.area > b.area;
  });
  if (labels_out) {
    *labels_out = cv::Mat1i(size, 0);
    for (int i = static_cast<int>(out.size()) - 1; i >= 0; --i)
      cv::drawContours(*labels_out, std::vector<std::vector<cv::Point>>{out[i].contour}, 0,
                       cv::Scalar(i + 1), cv::FILLED);
  }
  return out;
}

}  // namespace

std::vector<PhotoRegion> SegmentOptical(const cv::Mat& input, const OpticalSegmentOptions& opt,
                                        cv::Mat1i* labels_out) {
  opt.Check();
  return SegmentBgr(ToBgr(input), opt, labels_out);
}

std::vector<PhotoRegion> SegmentOptical(cv::Mat&& input, const OpticalSegmentOptions& opt, cv::Mat1i* labels_out) {
  opt.Check();
  cv::Mat3b bgr = ToBgr(input);
  input.release();
  return SegmentBgr(std::move(bgr), opt, labels_out);
}

cv::Mat DrawOpticalMaps(const cv::Mat& input, const OpticalSegmentOptions& opt) {
  opt.Check();
  const cv::Mat3b bgr = ToBgr(input);
  const Maps m = BuildMaps(bgr, opt);
  cv::Mat3b out = bgr * 0.5;
  out.setTo(cv::Scalar(0, 160, 0), m.veg);
  out.setTo(cv::Scalar(200, 60, 0), m.shadow & ~m.veg);
  out.setTo(cv::Scalar(0, 0, 255), m.edge == kTrueEdge);
  out.setTo(cv::Scalar(0, 255, 255), m.edge == kInRegionEdge);
  const int cell = opt.seed_cell;
  auto ok = [&](int y, int x) {
    return !m.veg(y, x) && !m.shadow(y, x) && m.edge(y, x) == kNoEdge;
  };
  auto mark = [&](int y, int x) {
    cv::drawMarker(out, {x, y}, cv::Scalar(255, 255, 255), cv::MARKER_CROSS, 5, 1);
  };
  for (int cy = 0; cy < bgr.rows; cy += cell)
    for (int cx = 0; cx < bgr.cols; cx += cell) {
      const int h = std::min(cell, bgr.rows - cy), w = std::min(cell, bgr.cols - cx);
      if (ok(cy + h / 2, cx + w / 2)) { mark(cy + h / 2, cx + w / 2); continue; }
      for (int sy = 0; sy < 2; ++sy)
        for (int sx = 0; sx < 2; ++sx) {
          const int yy = std::min(bgr.rows - 1, cy + h / 4 + sy * (h / 2));
          const int xx = std::min(bgr.cols - 1, cx + w / 4 + sx * (w / 2));
          if (ok(yy, xx)) mark(yy, xx);
        }
    }
  return out;
}

cv::Mat DrawPhotoRegions(const cv::Mat& input, const std::vector<PhotoRegion>& regions) {
  cv::Mat3b out = ToBgr(input).clone();
  const int thick = std::max(out.rows, out.cols) > 600 ? 2 : 1;
  for (size_t i = 0; i < regions.size(); ++i) {
    // Distinct hues (golden-angle steps), full saturation.
    cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<uint8_t>(int(i * 111.246) % 180), 255, 255)), c;
    cv::cvtColor(hsv, c, cv::COLOR_HSV2BGR);
    cv::polylines(out, regions[i].contour, true, cv::Scalar(c(0, 0)), thick, cv::LINE_8);
  }
  return out;
}

}  // namespace mvkp
