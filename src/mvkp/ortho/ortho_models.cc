#include "mvkp/ortho/ortho_models.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

cv::Mat1b ToGray(const cv::Mat& img) {
  Require(!img.empty() && img.depth() == CV_8U && (img.channels() == 1 || img.channels() == 3),
          ErrorCode::kInvalidArgument, "fBm fit: images must be 8-bit grey or BGR");
  cv::Mat1b g;
  if (img.channels() == 3) cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
  else g = img;
  return g;
}

std::array<double, 5> Augment(cv::Vec2d p) {
  return {p[0], p[1], p[0] * p[1], p[0] * p[0], p[1] * p[1]};
}

// Rasterises a polygon (float vertices), takes circular bites (occluding
// trees) out of it and returns its outer pixel contour.
std::vector<cv::Point> RasterContour(const std::vector<cv::Point2f>& poly, cv::Size size,
                                     const std::vector<cv::Vec3f>& bites = {}) {
  cv::Mat1b m(size, 0);
  std::vector<cv::Point> p;
  for (auto& q : poly) p.emplace_back(cvRound(q.x), cvRound(q.y));
  cv::fillPoly(m, std::vector<std::vector<cv::Point>>{p}, 255);
  for (const cv::Vec3f& b : bites) cv::circle(m, cv::Point(cvRound(b[0]), cvRound(b[1])), cvRound(b[2]), 0, cv::FILLED);
  std::vector<std::vector<cv::Point>> cs;
  cv::findContours(m, cs, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  if (cs.empty()) return {};
  return *std::max_element(cs.begin(), cs.end(), [](auto& a, auto& b) { return a.size() < b.size(); });
}

}  // namespace

FbmModel FitFbm(const std::vector<cv::Mat>& images, const std::vector<cv::Mat>& masks, int window,
                int stride, std::vector<cv::Mat1f>* ofe_maps) {
  Require(images.size() == masks.size() && !images.empty(), ErrorCode::kInvalidArgument,
          "fBm fit: need as many masks as images (and at least one)");
  Require(window >= 3 && window % 2 == 1 && window <= 31, ErrorCode::kInvalidArgument,
          "fBm fit: window must be odd, 3..31");
  Require(stride >= 1, ErrorCode::kInvalidArgument, "fBm fit: stride must be >= 1");
  const int r = window / 2;
  // d² -> (sum |dI|, count), indexed by d² (a table, not a map: this loop
  // runs ~25 times per sampled pixel)
  std::vector<std::pair<double, double>> by_d2(size_t(2 * r * r + 1), {0.0, 0.0});
  std::vector<cv::Mat1b> grays;
  size_t used = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    cv::Mat1b g = ToGray(images[i]);
    Require(masks[i].size() == g.size() && masks[i].type() == CV_8U, ErrorCode::kInvalidArgument,
            "fBm fit: mask " + std::to_string(i) + " must be CV_8U of the image's size");
    cv::Mat1b mk = masks[i];
    grays.push_back(g);
    for (int y = r; y < g.rows - r; y += stride)
      for (int x = r; x < g.cols - r; x += stride) {
        if (!mk(y, x)) continue;
        ++used;
        const int c = g(y, x);
        for (int dy = 0; dy <= r; ++dy)
          for (int dx = -r; dx <= r; ++dx) {
            if (dy == 0 && dx <= 0) continue;
            if (!mk(y + dy, x + dx)) continue;
            auto& s = by_d2[size_t(dx * dx + dy * dy)];
            s.first += std::abs(c - g(y + dy, x + dx));
            s.second += 1;
          }
      }
  }
  Require(used >= 500, ErrorCode::kInvalidArgument,
          "fBm fit: fewer than 500 usable non-building pixels");
  // Least squares: ln E|dI| = ln k + H ln d, one equation per distance.
  double sx = 0, sy = 0, sxx = 0, sxy = 0, n = 0;
  for (size_t d2 = 1; d2 < by_d2.size(); ++d2) {
    const auto& s = by_d2[d2];
    if (s.second < 10) continue;
    const double mean = std::max(s.first / s.second, 1e-3);
    const double lx = 0.5 * std::log(static_cast<double>(d2)), ly = std::log(mean);
    sx += lx; sy += ly; sxx += lx * lx; sxy += lx * ly; n += 1;
  }
  Require(n >= 3, ErrorCode::kInvalidArgument, "fBm fit: too few distinct distances");
  FbmModel m;
  m.window = window;
  const double den = n * sxx - sx * sx;
  m.H = std::clamp((n * sxy - sx * sy) / den, 0.02, 0.98);
  m.k = std::exp((sy - m.H * sx) / n);
  // Natural OFE level: mean OFE over the masked training pixels.
  m.ofe = 1;  // placeholder so OverallFractalError accepts the model
  double sum = 0, cnt = 0;
  if (ofe_maps) ofe_maps->clear();
  for (size_t i = 0; i < grays.size(); ++i) {
    cv::Mat1f ofe = OverallFractalError(grays[i], m);  // the map does not depend on m.ofe
    cv::Mat1b mk = masks[i];
    for (int y = r; y < ofe.rows - r; y += stride)
      for (int x = r; x < ofe.cols - r; x += stride)
        if (mk(y, x)) { sum += ofe(y, x); cnt += 1; }
    if (ofe_maps) ofe_maps->push_back(std::move(ofe));
  }
  m.ofe = std::max(sum / std::max(cnt, 1.0), 1e-3);
  return m;
}

namespace {
cv::Mat1f OverallFractalErrorWhole(const cv::Mat1b& gray, const FbmModel& model) {
  const int r = model.window / 2;
  cv::Mat1f f;
  gray.convertTo(f, CV_32F);
  cv::Mat1f acc(gray.size(), 0.f), diff(gray.size()), mean, cls;
  int classes = 0;
  // Distance classes: axis offsets (d, 0), (0, d) and diagonal (d, d), (d, -d).
  for (int d = 1; d <= r; ++d)
    for (int diag = 0; diag < 2; ++diag) {
      const cv::Point offs[2] = {diag ? cv::Point(d, d) : cv::Point(d, 0), diag ? cv::Point(d, -d) : cv::Point(0, d)};
      cls = cv::Mat1f(gray.size(), 0.f);
      for (const cv::Point o : offs) {
        // diff(p) = |I(p) - I(p + o)| where both inside; replicate at the border.
        diff.setTo(0);
        const int x0 = std::max(0, -o.x), x1 = gray.cols - std::max(0, o.x);
        const int y0 = std::max(0, -o.y), y1 = gray.rows - std::max(0, o.y);
        if (x1 <= x0 || y1 <= y0) continue;
        const cv::Rect a(x0, y0, x1 - x0, y1 - y0), b = a + o;
        cv::absdiff(f(a), f(b), diff(a));
        cv::boxFilter(diff, mean, CV_32F, cv::Size(model.window, model.window));
        cls += mean;
      }
      const float pred = static_cast<float>(model.k * std::pow(d * (diag ? std::sqrt(2.0) : 1.0), model.H));
      cls = cls * 0.5f - pred;
      acc += cls.mul(cls);
      ++classes;
    }
  cv::Mat1f out;
  cv::sqrt(acc / classes, out);
  return out;
}
}  // namespace

cv::Mat1f OverallFractalError(const cv::Mat1b& gray, const FbmModel& model, int strip_rows) {
  Require(model.Valid(), ErrorCode::kInvalidArgument, "fractal error: invalid fBm model");
  Require(strip_rows >= 0, ErrorCode::kInvalidArgument, "fractal error: strip_rows must be >= 0");
  // Row strips with a halo of window/2 (box filter) + window/2 (pixel
  // differences): each output row sees exactly the pixels it would see in
  // the whole image, so the result is identical; the ~8 float work maps then
  // cover a strip, not the photo (about 30 bytes per photo pixel saved).
  const int halo = 2 * (model.window / 2);
  if (strip_rows == 0 || gray.rows <= strip_rows + 2 * halo) return OverallFractalErrorWhole(gray, model);
  cv::Mat1f out(gray.size());
  for (int y0 = 0; y0 < gray.rows; y0 += strip_rows) {
    const int y1 = std::min(gray.rows, y0 + strip_rows);
    const int a = std::max(0, y0 - halo), b = std::min(gray.rows, y1 + halo);
    const cv::Mat1f part = OverallFractalErrorWhole(gray.rowRange(a, b), model);
    part.rowRange(y0 - a, y1 - a).copyTo(out.rowRange(y0, y1));
  }
  return out;
}

bool RegionLda::Valid() const {
  bool nz = false;
  for (double v : w) {
    if (!std::isfinite(v)) return false;
    nz |= v != 0;
  }
  return nz && std::isfinite(b);
}

double RegionLda::Score(cv::Vec2d pnr) const {
  const auto f = Augment(pnr);
  double s = b;
  for (int i = 0; i < 5; ++i) s += w[i] * f[i];
  return s;
}

cv::Vec2d ContourPnr(const std::vector<cv::Point>& contour, int bins) {
  if (contour.size() < 3 || bins < 4) return {1, 1};
  // Dominant direction modulo 90°: peak of a length-weighted 18-bin histogram
  // of edge directions of a simplified polygon (robust to image-border cuts),
  // refined by the mean of 4θ over the edges near the peak.
  std::vector<cv::Point> poly;
  cv::approxPolyDP(contour, poly, 1.5, true);
  if (poly.size() < 3) poly = contour;
  std::vector<double> len(poly.size()), ang(poly.size());  // ang in [0, 90) degrees
  double hist[18] = {};
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point d = poly[(i + 1) % poly.size()] - poly[i];
    len[i] = std::hypot(d.x, d.y);
    ang[i] = std::fmod(std::atan2(d.y, d.x) * 180 / std::numbers::pi + 360.0, 90.0);
    hist[std::min(17, static_cast<int>(ang[i] / 5))] += len[i];
  }
  int peak = 0;
  double best = -1;
  for (int b = 0; b < 18; ++b) {
    const double v = hist[(b + 17) % 18] + 2 * hist[b] + hist[(b + 1) % 18];
    if (v > best) { best = v; peak = b; }
  }
  const double centre = peak * 5 + 2.5;
  double sc = 0, ss = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    double diff = std::abs(ang[i] - centre);
    diff = std::min(diff, 90 - diff);
    if (diff > 10) continue;
    const double th = ang[i] * std::numbers::pi / 180;
    sc += len[i] * std::cos(4 * th);
    ss += len[i] * std::sin(4 * th);
  }
  const double th0 = 0.25 * std::atan2(ss, sc), c = std::cos(th0), s = std::sin(th0);
  // Densify to 1 px steps and rotate by -th0.
  std::vector<cv::Point2d> pts;
  for (size_t i = 0; i < contour.size(); ++i) {
    const cv::Point a = contour[i], b = contour[(i + 1) % contour.size()];
    const int steps = std::max(1, std::max(std::abs(b.x - a.x), std::abs(b.y - a.y)));
    for (int k = 0; k < steps; ++k) {
      const double x = a.x + (b.x - a.x) * double(k) / steps, y = a.y + (b.y - a.y) * double(k) / steps;
      pts.emplace_back(c * x + s * y, -s * x + c * y);
    }
  }
  auto pnr_of = [&](bool use_x) {
    double lo = 1e300, hi = -1e300;
    for (auto& p : pts) {
      const double v = use_x ? p.x : p.y;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    if (hi - lo < 1e-9) return 1.0;
    std::vector<double> h(bins, 0);
    for (auto& p : pts) {
      const double v = use_x ? p.x : p.y;
      h[std::min(bins - 1, static_cast<int>((v - lo) / (hi - lo) * bins))] += 1;
    }
    const int p1 = static_cast<int>(std::max_element(h.begin(), h.end()) - h.begin());
    double nb = 0, nn = 0;
    if (p1 > 0) { nb += h[p1 - 1]; nn += 1; }
    if (p1 + 1 < bins) { nb += h[p1 + 1]; nn += 1; }
    const double r1 = nb / nn / h[p1];
    double second = 0;
    for (int i = 0; i < bins; ++i)
      if (std::abs(i - p1) >= 2) second = std::max(second, h[i]);
    return 0.5 * (r1 + second / h[p1]);
  };
  return {pnr_of(true), pnr_of(false)};
}

RegionLda TrainRegionLda(const std::vector<cv::Vec2d>& pnr, const std::vector<int>& labels) {
  Require(pnr.size() == labels.size(), ErrorCode::kInvalidArgument,
          "LDA training: as many labels as samples needed");
  cv::Matx<double, 5, 1> mu[2];
  int n[2] = {0, 0};
  for (size_t i = 0; i < pnr.size(); ++i) {
    Require(labels[i] == 0 || labels[i] == 1, ErrorCode::kInvalidArgument,
            "LDA training: labels must be 0 or 1");
    const auto f = Augment(pnr[i]);
    for (int j = 0; j < 5; ++j) mu[labels[i]](j) += f[j];
    ++n[labels[i]];
  }
  Require(n[0] >= 3 && n[1] >= 3, ErrorCode::kInvalidArgument,
          "LDA training: need at least 3 samples of each class");
  for (int c = 0; c < 2; ++c) mu[c] *= 1.0 / n[c];
  cv::Matx<double, 5, 5> cov;
  for (size_t i = 0; i < pnr.size(); ++i) {
    const auto f = Augment(pnr[i]);
    cv::Matx<double, 5, 1> d;
    for (int j = 0; j < 5; ++j) d(j) = f[j] - mu[labels[i]](j);
    cov += d * d.t();
  }
  cov *= 1.0 / std::max(1, n[0] + n[1] - 2);
  double tr = 0;
  for (int j = 0; j < 5; ++j) tr += cov(j, j);
  for (int j = 0; j < 5; ++j) cov(j, j) += 1e-6 * tr / 5 + 1e-12;
  const cv::Matx<double, 5, 1> w = cov.inv(cv::DECOMP_SVD) * (mu[1] - mu[0]);
  RegionLda m;
  for (int j = 0; j < 5; ++j) m.w[j] = w(j);
  m.b = -0.5 * (w.t() * (mu[1] + mu[0]))(0) + std::log(double(n[1]) / n[0]);
  return m;
}

void DefaultRegionLdaTrainingSet(std::vector<cv::Vec2d>* pnr, std::vector<int>* labels,
                                 unsigned seed) {
  cv::RNG rng(seed);
  const cv::Size sz(320, 320);
  const cv::Point2f ctr(160, 160);
  auto place = [&](std::vector<cv::Point2f> poly, double jitter, int n_bites, float bite_size) {
    const double a = rng.uniform(0.0, std::numbers::pi);
    const double c = std::cos(a), s = std::sin(a);
    for (auto& p : poly) {
      const float x = p.x + static_cast<float>(rng.gaussian(jitter));
      const float y = p.y + static_cast<float>(rng.gaussian(jitter));
      p = ctr + cv::Point2f(static_cast<float>(c * x - s * y), static_cast<float>(s * x + c * y));
    }
    std::vector<cv::Vec3f> bites;
    for (int k = 0; k < n_bites; ++k) {  // centred on a random boundary point
      const size_t i = static_cast<size_t>(rng.uniform(0, static_cast<int>(poly.size())));
      const cv::Point2f q = poly[i] + (poly[(i + 1) % poly.size()] - poly[i]) * rng.uniform(0.f, 1.f);
      bites.emplace_back(q.x, q.y, bite_size * rng.uniform(0.15f, 0.4f));
    }
    return RasterContour(poly, sz, bites);
  };
  auto add = [&](const std::vector<cv::Point>& ct, int label) {
    if (ct.size() < 8) return;
    pnr->push_back(ContourPnr(ct));
    labels->push_back(label);
  };
  for (int i = 0; i < 400; ++i) {
    // Buildings: rectangles and L/T/U outlines, 12..140 px, slight jitter.
    const float w = static_cast<float>(rng.uniform(12.0, 140.0));
    const float h = static_cast<float>(w * rng.uniform(0.3, 1.0));
    const float t = static_cast<float>(rng.uniform(0.3, 0.6));
    std::vector<cv::Point2f> poly;
    switch (i % 4) {
      case 0: case 1:
        poly = {{-w / 2, -h / 2}, {w / 2, -h / 2}, {w / 2, h / 2}, {-w / 2, h / 2}};
        break;
      case 2:  // L
        poly = {{-w / 2, -h / 2}, {-w / 2 + t * w, -h / 2}, {-w / 2 + t * w, h / 2 - t * h},
                {w / 2, h / 2 - t * h}, {w / 2, h / 2}, {-w / 2, h / 2}};
        break;
      default:  // T / U
        if (rng.uniform(0, 2) == 0)
          poly = {{-w / 2, -h / 2}, {w / 2, -h / 2}, {w / 2, -h / 2 + t * h}, {t * w / 2, -h / 2 + t * h},
                  {t * w / 2, h / 2}, {-t * w / 2, h / 2}, {-t * w / 2, -h / 2 + t * h}, {-w / 2, -h / 2 + t * h}};
        else
          poly = {{-w / 2, -h / 2}, {-w / 2 + t * w / 2, -h / 2}, {-w / 2 + t * w / 2, h / 2 - t * h},
                  {w / 2 - t * w / 2, h / 2 - t * h}, {w / 2 - t * w / 2, -h / 2}, {w / 2, -h / 2},
                  {w / 2, h / 2}, {-w / 2, h / 2}};
    }
    // A third of them partly hidden by trees.
    add(place(poly, 0.7, i % 3 == 0 ? rng.uniform(1, 3) : 0, std::min(w, h)), 1);
  }
  for (int i = 0; i < 400; ++i) {
    std::vector<cv::Point2f> poly;
    const double R = rng.uniform(8.0, 70.0);
    if (i % 2 == 0) {  // smooth or lumpy blobs
      double amp[7], ph[7];
      for (int k = 2; k < 7; ++k) { amp[k] = rng.uniform(0.0, 0.25); ph[k] = rng.uniform(0.0, 6.3); }
      for (int j = 0; j < 72; ++j) {
        const double a = j * std::numbers::pi / 36;
        double rr = 1;
        for (int k = 2; k < 7; ++k) rr += amp[k] * std::cos(k * a + ph[k]);
        rr *= R * rng.uniform(0.93, 1.07);
        poly.emplace_back(static_cast<float>(rr * std::cos(a)), static_cast<float>(rr * std::sin(a)));
      }
    } else {  // random star polygons (leaks, irregular clutter)
      const int nv = rng.uniform(5, 12);
      for (int j = 0; j < nv; ++j) {
        const double a = (j + rng.uniform(-0.3, 0.3)) * 2 * std::numbers::pi / nv;
        const double rr = R * rng.uniform(0.35, 1.0);
        poly.emplace_back(static_cast<float>(rr * std::cos(a)), static_cast<float>(rr * std::sin(a)));
      }
    }
    add(place(poly, 0.0, 0, 0.f), 0);
  }
}

RegionLda DefaultRegionLda() {
  static const RegionLda model = [] {
    std::vector<cv::Vec2d> p;
    std::vector<int> l;
    DefaultRegionLdaTrainingSet(&p, &l);
    return TrainRegionLda(p, l);
  }();
  return model;
}

namespace {

cv::FileStorage OpenRead(const std::string& path, const char* what) {
  Require(std::filesystem::exists(path), ErrorCode::kIo, std::string(what) + ": no file " + path);
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ | cv::FileStorage::FORMAT_JSON);
  } catch (const cv::Exception&) {
    throw Error(ErrorCode::kBadModel, std::string(what) + ": not a JSON model file: " + path);
  }
  Require(fs.isOpened(), ErrorCode::kIo, std::string(what) + ": cannot read " + path);
  return fs;
}

void CheckType(const cv::FileStorage& fs, const std::string& want, const std::string& path) {
  std::string type;
  if (!fs["type"].empty()) fs["type"] >> type;
  Require(type == want, ErrorCode::kBadModel, path + ": expected a model of type " + want);
}

cv::FileStorage OpenWrite(const std::string& path, const char* what) {
  cv::FileStorage fs(path, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_JSON);
  Require(fs.isOpened(), ErrorCode::kIo, std::string(what) + ": cannot write " + path);
  return fs;
}

}  // namespace

void SaveFbmModel(const std::string& path, const FbmModel& m) {
  Require(m.Valid(), ErrorCode::kInvalidArgument, "fBm model: refusing to save an invalid model");
  cv::FileStorage fs = OpenWrite(path, "fBm model");
  fs << "type" << "mvkp.fbm" << "version" << 1 << "k" << m.k << "H" << m.H << "ofe" << m.ofe
     << "window" << m.window;
}

FbmModel LoadFbmModel(const std::string& path) {
  cv::FileStorage fs = OpenRead(path, "fBm model");
  CheckType(fs, "mvkp.fbm", path);
  FbmModel m;
  Require(!fs["k"].empty() && !fs["H"].empty() && !fs["ofe"].empty() && !fs["window"].empty(),
          ErrorCode::kBadModel, path + ": fBm model lacks k, H, ofe or window");
  fs["k"] >> m.k;
  fs["H"] >> m.H;
  fs["ofe"] >> m.ofe;
  fs["window"] >> m.window;
  Require(m.Valid(), ErrorCode::kBadModel, path + ": fBm model values out of range");
  return m;
}

void SaveRegionLda(const std::string& path, const RegionLda& m) {
  Require(m.Valid(), ErrorCode::kInvalidArgument, "region LDA: refusing to save an invalid model");
  cv::FileStorage fs = OpenWrite(path, "region LDA");
  fs << "type" << "mvkp.region_lda" << "version" << 1 << "features"
     << "pnr_x,pnr_y,pnr_x*pnr_y,pnr_x^2,pnr_y^2" << "w" << "[";
  for (double v : m.w) fs << v;
  fs << "]" << "b" << m.b;
}

RegionLda LoadRegionLda(const std::string& path) {
  cv::FileStorage fs = OpenRead(path, "region LDA");
  CheckType(fs, "mvkp.region_lda", path);
  cv::FileNode w = fs["w"];
  Require(w.isSeq() && w.size() == 5 && !fs["b"].empty(), ErrorCode::kBadModel,
          path + ": region LDA needs w (5 numbers) and b");
  RegionLda m;
  for (int i = 0; i < 5; ++i) m.w[i] = static_cast<double>(w[i]);
  fs["b"] >> m.b;
  Require(m.Valid(), ErrorCode::kBadModel, path + ": region LDA values are not finite");
  return m;
}

}  // namespace mvkp
