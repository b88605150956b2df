#include "mvkp/ortho/shadows.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>
#include <opencv2/imgproc.hpp>
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void ShadowOptions::Check() const {
  auto req = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, std::string("shadow compensation: ") + m); };
  req(pre_blur_sigma >= 0 && pre_blur_sigma <= 10, "pre_blur_sigma must be in [0, 10]");
  req(edge_offset >= 1 && edge_offset <= 20, "edge_offset must be in [1, 20]");
  req(max_side_sd > 0, "max_side_sd must be > 0");
  req(side_window >= 1 && side_window <= 15 && side_window % 2 == 1, "side_window must be odd, in [1, 15]");
  req(min_step > 0 && min_step < 5, "min_step must be in (0, 5)");
  req(min_tint >= 0, "min_tint must be >= 0");
  req(mode_window > 0 && mode_window < 1, "mode_window must be in (0, 1)");
  req(min_votes >= 1, "min_votes must be >= 1");
  req(max_samples >= 100, "max_samples must be >= 100");
  req(match_eps > 0 && match_eps < 1, "match_eps must be in (0, 1)");
  req(ring_dirs >= 4 && ring_dirs <= 64, "ring_dirs must be in [4, 64]");
  req(grow_tol >= 0 && grow_tol < 1, "grow_tol must be in [0, 1)");
  req(grow_window >= 3 && grow_window <= 101 && grow_window % 2 == 1, "grow_window must be odd, in [3, 101]");
  req(grow_up >= 0, "grow_up must be >= 0");
  req(grow_rounds >= 0 && grow_rounds <= 1000, "grow_rounds must be in [0, 1000]");
  req(max_fraction > 0 && max_fraction <= 1, "max_fraction must be in (0, 1]");
  req(feather_sigma >= 0 && feather_sigma <= 10, "feather_sigma must be in [0, 10]");
  req(work_max_side == 0 || work_max_side >= 64, "work_max_side must be 0 or >= 64");
}

namespace {

constexpr float kLogOffset = 6.f;  // log(I + 6): dark pixels' noise does not explode

constexpr int kBandRows = 64;  // rows per band of the banded passes (memory: no full-size float maps)

// The mean log colour (log intensity) of a pixel; computed where needed
// rather than kept as a full-size map.
inline float LogMean(const cv::Vec3f& l) { return (l[0] + l[1] + l[2]) / 3.f; }

// pass(y, x) = 1 where the pixel passes the growth test against the mask's
// mean colour over the win x win window around it (some mask pixel there;
// every channel within tol of the mean; mean log intensity not above the
// mean's by more than up). Computed in bands of rows with their halo, so
// its working maps are a band's, not the photo's.
void PassMap(const cv::Mat3f& L, const cv::Mat1b& m, int win, float tol, float up,
             cv::Mat1b& pass) {
  const int H = L.rows, W = L.cols, r = win / 2;
  const cv::Size ksize(win, win);
  cv::Mat1f mf, cnt;
  cv::Mat3f Lm, sum;
  for (int y0 = 0; y0 < H; y0 += kBandRows) {
    const int y1 = std::min(H, y0 + kBandRows), a = std::max(0, y0 - r), b = std::min(H, y1 + r);
    const cv::Mat1b mb = m.rowRange(a, b);
    mb.convertTo(mf, CV_32F);
    cv::boxFilter(mf, cnt, -1, ksize, cv::Point(-1, -1), false);
    Lm.create(b - a, W);
    Lm.setTo(cv::Scalar::all(0));
    L.rowRange(a, b).copyTo(Lm, mb);
    cv::boxFilter(Lm, sum, -1, ksize, cv::Point(-1, -1), false);
    for (int y = y0; y < y1; ++y) {
      const float* c = cnt[y - a];
      const cv::Vec3f* sm = sum[y - a];
      const cv::Vec3f* v = L[y];
      uint8_t* p = pass[y];
      for (int x = 0; x < W; ++x) {
        p[x] = 0;
        if (c[x] < 0.5f) continue;
        const cv::Vec3f mean = sm[x] / c[x];
        if (std::abs(v[x][0] - mean[0]) >= tol || std::abs(v[x][1] - mean[1]) >= tol ||
            std::abs(v[x][2] - mean[2]) >= tol)
          continue;
        p[x] = LogMean(v[x]) <= (mean[0] + mean[1] + mean[2]) / 3.f + up;
      }
    }
  }
}

// The densest mode of the steps (mean shift, Chebyshev window), from evenly
// spaced starts. Returns the votes in the mode.
int Mode(const std::vector<cv::Vec3f>& d, double win, cv::Vec3f* best) {
  int best_votes = 0;
  const int starts = std::min<int>(60, int(d.size()));
  auto within = [&](const cv::Vec3f& a, const cv::Vec3f& c) {
    return std::abs(a[0] - c[0]) < win && std::abs(a[1] - c[1]) < win && std::abs(a[2] - c[2]) < win;
  };
  for (int s = 0; s < starts; ++s) {
    cv::Vec3f c = d[size_t(s) * d.size() / starts];
    int n = 0;
    for (int it = 0; it < 20; ++it) {
      cv::Vec3d sum(0, 0, 0);
      n = 0;
      for (const auto& v : d)
        if (within(v, c)) sum += cv::Vec3d(v), ++n;
      if (n == 0) break;
      const cv::Vec3f nc(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n));
      const bool still = cv::norm(nc - c) < 1e-4;
      c = nc;
      if (still) break;
    }
    n = 0;
    for (const auto& v : d) n += within(v, c);
    if (n > best_votes) best_votes = n, *best = c;
  }
  return best_votes;
}

}  // namespace

cv::Mat CompensateShadows(const cv::Mat& bgr, const ShadowOptions& o, ShadowCompensation* info, cv::Mat1b* mask) {
  o.Check();
  Timer timer;
  ShadowCompensation local;
  ShadowCompensation& inf = info ? *info : local;
  inf = ShadowCompensation{};
  if (mask) mask->release();
  if (bgr.empty()) return bgr;
  Require(bgr.depth() == CV_8U, ErrorCode::kBadImage, "shadow compensation: the photo must be 8-bit");
  if (!o.enabled || bgr.channels() != 3 || bgr.rows < 16 || bgr.cols < 16) return bgr;
  // The step, the seeds and the growth at most work_max_side px across
  // (shadows there are still tens of px wide); the relighting at full size.
  cv::Mat3b small;
  const double k = o.work_max_side > 0 ? std::min(1.0, double(o.work_max_side) / std::max(bgr.cols, bgr.rows)) : 1.0;
  if (k < 1) cv::resize(bgr, small, cv::Size(), k, k, cv::INTER_AREA);
  else small = bgr;
  const int H = small.rows, W = small.cols;

  // Log colours of the smoothed photo, and their mean (log intensity).
  // (In bands of rows with a halo: a full-size float copy for the blur would
  // double the peak.)
  cv::Mat3f L(H, W);
  {
    const int halo = o.pre_blur_sigma > 0 ? int(std::ceil(4 * o.pre_blur_sigma)) + 1 : 0;
    cv::Mat3f band;
    for (int y0 = 0; y0 < H; y0 += kBandRows) {
      const int y1 = std::min(H, y0 + kBandRows), a = std::max(0, y0 - halo), b = std::min(H, y1 + halo);
      small.rowRange(a, b).convertTo(band, CV_32FC3);
      if (o.pre_blur_sigma > 0) cv::GaussianBlur(band, band, cv::Size(), o.pre_blur_sigma);
      cv::Mat3f rows = L.rowRange(y0, y1);
      band.rowRange(y0 - a, y1 - a).copyTo(rows);
      rows += cv::Scalar::all(kLogOffset);
      cv::log(rows, rows);
    }
  }

  // 1. The step: dark minus bright across edges with uniform sides.
  if (o.log_step[0] < 0 && o.log_step[1] < 0 && o.log_step[2] < 0) {
    inf.log_step = o.log_step;  // given
  } else {
    cv::Mat1b edges;
    {
      cv::Mat1b grey;
      cv::cvtColor(small, grey, cv::COLOR_BGR2GRAY);
      cv::Canny(grey, edges, 30, 80);
    }
    // The gradient (3x3 Sobel) and the sides' variance (side_window box) at
    // the sampled points only: full-size maps of them cost 16 bytes a pixel.
    // (the border as cv::Sobel and cv::blur treat it, BORDER_REFLECT_101)
    auto in = [](int i, int n) {
      return unsigned(i) < unsigned(n) ? i : cv::borderInterpolate(i, n, cv::BORDER_REFLECT_101);
    };
    auto at = [&](int x, int y) { return LogMean(L(in(y, H), in(x, W))); };
    const int sr = o.side_window / 2;
    const float inv_area = 1.f / float(o.side_window * o.side_window);
    auto var = [&](int x, int y) {
      float s1 = 0, s2 = 0;
      for (int v = y - sr; v <= y + sr; ++v)
        for (int u = x - sr; u <= x + sr; ++u) {
          const float a = at(u, v);
          s1 += a, s2 += a * a;
        }
      s1 *= inv_area, s2 *= inv_area;
      return s2 - s1 * s1;
    };
    std::vector<cv::Point> pts;
    for (int y = 0; y < H; ++y) {
      const uint8_t* e = edges[y];
      for (int x = 0; x < W; ++x)
        if (e[x]) pts.emplace_back(x, y);
    }
    edges.release();
    const size_t stride = std::max<size_t>(1, (pts.size() + o.max_samples - 1) / o.max_samples);
    const float sd2 = float(o.max_side_sd * o.max_side_sd);
    std::vector<cv::Vec3f> steps;
    for (size_t i = 0; i < pts.size(); i += stride) {
      const cv::Point p = pts[i];
      const float dx = (at(p.x + 1, p.y - 1) - at(p.x - 1, p.y - 1)) + 2 * (at(p.x + 1, p.y) - at(p.x - 1, p.y)) +
                       (at(p.x + 1, p.y + 1) - at(p.x - 1, p.y + 1));
      const float dy = (at(p.x - 1, p.y + 1) - at(p.x - 1, p.y - 1)) + 2 * (at(p.x, p.y + 1) - at(p.x, p.y - 1)) +
                       (at(p.x + 1, p.y + 1) - at(p.x + 1, p.y - 1));
      const float mag = std::sqrt(dx * dx + dy * dy);
      if (mag < 1e-6f) continue;
      // the farthest offset (of edge_offset + 2 .. edge_offset) whose two
      // sides are uniform: past a soft shadow edge's ramp where it is wide
      // enough, still inside a narrow one
      for (int off = o.edge_offset + 2; off >= o.edge_offset; --off) {
        // a: brighter side (the gradient points up the intensity), b: darker
        const int xa = int(std::lround(p.x + off * dx / mag)), ya = int(std::lround(p.y + off * dy / mag));
        const int xb = int(std::lround(p.x - off * dx / mag)), yb = int(std::lround(p.y - off * dy / mag));
        if (xa < 0 || ya < 0 || xb < 0 || yb < 0 || xa >= W || xb >= W || ya >= H || yb >= H) continue;
        if (var(xa, ya) >= sd2 || var(xb, yb) >= sd2) continue;
        const cv::Vec3f d = L(yb, xb) - L(ya, xa);
        const float mean = (d[0] + d[1] + d[2]) / 3.f;
        if (d[0] >= -0.1f || d[1] >= -0.1f || d[2] >= -0.1f || mean >= -o.min_step) continue;
        // blue drops least, red most (a sky bluer than the sun)
        if ((d[0] - d[2]) < o.min_tint * -mean || d[1] < d[2] - 0.02f || d[0] < d[1] - 0.02f) continue;
        steps.push_back(d);
        break;
      }
    }
    inf.samples = int(steps.size());
    if (int(steps.size()) < o.min_votes) {
      inf.ms = timer.ElapsedMs();
      return bgr;
    }
    cv::Vec3f best;
    inf.votes = Mode(steps, o.mode_window, &best);
    if (inf.votes < o.min_votes) {
      inf.ms = timer.ElapsedMs();
      return bgr;
    }
    inf.log_step = cv::Vec3d(best);
  }
  const cv::Vec3f d(inf.log_step);
  const float dmean = (d[0] + d[1] + d[2]) / 3.f;

  // 2. Seeds: the pixel lit again matches a ring pixel. Only pixels with a
  // ring-reach neighbour at least as bright as their relit self are tried
  // (that neighbourhood's maximum, in bands of rows: memory).
  const int rmax = 16;
  std::vector<cv::Point> ring;
  for (int r : {3, 6, 10, 16})
    for (int k = 0; k < o.ring_dirs; ++k) {
      const double a = 2 * CV_PI * k / o.ring_dirs;
      ring.emplace_back(int(std::lround(r * std::cos(a))), int(std::lround(r * std::sin(a))));
    }
  const float eps = float(o.match_eps);
  cv::Mat1b m(H, W, uint8_t(0));
  {
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * rmax + 1, 2 * rmax + 1));
    cv::Mat1f lband, lmax;
    for (int y0 = 0; y0 < H; y0 += kBandRows) {
      const int y1 = std::min(H, y0 + kBandRows), a = std::max(0, y0 - rmax), b = std::min(H, y1 + rmax);
      lband.create(b - a, W);
      for (int y = a; y < b; ++y)
        for (int x = 0; x < W; ++x) lband(y - a, x) = LogMean(L(y, x));
      cv::dilate(lband, lmax, kernel);
      for (int y = y0; y < y1; ++y) {
        const cv::Vec3f* l = L[y];
        const float* mx = lmax[y - a];
        for (int x = 0; x < W; ++x) {
          if (LogMean(l[x]) - dmean > mx[x] + eps) continue;
          const cv::Vec3f rl = l[x] - d;
          for (const cv::Point& q : ring) {
            const int qx = x + q.x, qy = y + q.y;
            if (qx < 0 || qy < 0 || qx >= W || qy >= H) continue;
            const cv::Vec3f& v = L(qy, qx);
            if (std::abs(v[0] - rl[0]) < eps && std::abs(v[1] - rl[1]) < eps && std::abs(v[2] - rl[2]) < eps) {
              m(y, x) = 1;
              break;
            }
          }
        }
      }
    }
  }
  cv::morphologyEx(m, m, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2, 2)));

  // 3. Growth, round by round: the mask's mean colour over the window is
  // fixed within a round, so which pixels pass against it is a map of the
  // round (PassMap, in bands of rows); a flood through them.
  cv::Mat1b pass(H, W);
  std::deque<cv::Point> queue;
  for (int round = 0; round < o.grow_rounds; ++round) {
    PassMap(L, m, o.grow_window, float(o.grow_tol), float(o.grow_up), pass);
    int grown = 0;
    queue.clear();
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        if (m(y, x)) queue.emplace_back(x, y);
    while (!queue.empty()) {
      const cv::Point p = queue.front();
      queue.pop_front();
      for (int k = 0; k < 8; ++k) {
        static const int kx[8] = {1, -1, 0, 0, 1, 1, -1, -1}, ky[8] = {0, 0, 1, -1, 1, -1, 1, -1};
        const int x = p.x + kx[k], y = p.y + ky[k];
        if (x < 0 || y < 0 || x >= W || y >= H || m(y, x) || !pass(y, x)) continue;
        m(y, x) = 1, ++grown;
        queue.emplace_back(x, y);
      }
    }
    if (grown == 0) break;
  }
  pass.release();
  L.release();
  std::deque<cv::Point>().swap(queue);

  const int n = cv::countNonZero(m);
  inf.fraction = double(n) / (double(W) * H);
  if (n == 0 || inf.fraction > o.max_fraction) {
    inf.ms = timer.ElapsedMs();
    return bgr;
  }
  // 4. Relight: (I + offset) * exp(-d * mask) - offset.
  cv::Mat1f soft;
  m.convertTo(soft, CV_32F);
  if (k < 1) cv::resize(soft, soft, bgr.size(), 0, 0, cv::INTER_LINEAR);
  if (o.feather_sigma > 0) cv::GaussianBlur(soft, soft, cv::Size(), o.feather_sigma);
  cv::Mat3b out(bgr.rows, bgr.cols);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* s = bgr.ptr<cv::Vec3b>(y);
    const float* w = soft[y];
    cv::Vec3b* t = out[y];
    for (int x = 0; x < bgr.cols; ++x) {
      if (w[x] < 1e-3f) {
        t[x] = s[x];
        continue;
      }
      for (int c = 0; c < 3; ++c) {
        const float v = (s[x][c] + kLogOffset) * std::exp(-d[c] * w[x]) - kLogOffset;
        t[x][c] = cv::saturate_cast<uint8_t>(v);
      }
    }
  }
  if (mask) {
    *mask = soft > 0.5f;
  }
  inf.applied = true;
  inf.ms = timer.ElapsedMs();
  return out;
}

}  // namespace mvkp
