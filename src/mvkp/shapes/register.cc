#include "mvkp/shapes/register.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <random>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void RegistrationOptions::Check() const {
  shape.Check();
  auto need = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, m); };
  need(partial_min_corners >= 4 && max_partials_per_region >= 0,
       "RegistrationOptions: partial_min_corners >= 4, max_partials_per_region >= 0");
  need(min_region_area >= 0, "RegistrationOptions.min_region_area must be >= 0");
  need(candidates_per_region >= 1 && shifts_per_pair >= 1 && max_hypotheses >= 1,
       "RegistrationOptions: candidates_per_region, shifts_per_pair, max_hypotheses must be >= 1");
  need(min_scale > 0 && max_scale > min_scale, "RegistrationOptions: need 0 < min_scale < max_scale");
  need(inlier_px > 0 && inlier_fraction > 0 && inlier_fraction <= 1,
       "RegistrationOptions: inlier_px > 0, inlier_fraction in (0, 1]");
  need(max_area_ratio >= 1, "RegistrationOptions.max_area_ratio must be >= 1");
  need(max_perspective >= 0 && std::isfinite(max_perspective), "RegistrationOptions.max_perspective must be >= 0");
  need(max_anisotropy == 0 || (max_anisotropy >= 1 && std::isfinite(max_anisotropy)),
       "RegistrationOptions.max_anisotropy must be 0 (off) or >= 1");
  need(joint_lean_gain >= 0 && std::isfinite(joint_lean_gain), "RegistrationOptions.joint_lean_gain must be >= 0");
  need(lean_min_roof_ratio >= 0 && lean_min_roof_ratio <= 2, "RegistrationOptions.lean_min_roof_ratio in [0, 2]");
  need(min_regions >= 2 && min_regions_with_evidence >= 2,
       "RegistrationOptions: min_regions and min_regions_with_evidence must be >= 2");
  need(min_inlier_ratio >= 0 && min_inlier_ratio <= 1 && min_inlier_ratio_with_evidence >= 0 &&
           min_inlier_ratio_with_evidence <= 1,
       "RegistrationOptions: min_inlier_ratio and min_inlier_ratio_with_evidence in [0, 1]");
  need(max_rms_px > 0, "RegistrationOptions.max_rms_px must be > 0");
  need(single_pair_min_seed_contrast >= 0 && single_pair_distinct_px > 0 && single_pair_poses >= 2 &&
           single_pair_min_outlines >= 3 && single_pair_min_on_edges >= 0 && single_pair_min_on_edges <= 1 &&
           single_pair_min_confidence >= 0 && single_pair_min_confidence <= 1,
       "RegistrationOptions: single_pair_* out of range");
  need(std::isfinite(ambiguity_px) && ambiguity_px >= 0 && std::isfinite(ambiguity_perspective) &&
           ambiguity_perspective > 0 && ambiguity_perspective < 1,
       "RegistrationOptions: ambiguity_px must be >= 0 and ambiguity_perspective in (0, 1)");
  need(grow_tolerance >= 1 && grow_tolerance <= 4, "RegistrationOptions.grow_tolerance in [1, 4]");
  need(perspective_min_pairs >= 4, "RegistrationOptions.perspective_min_pairs must be >= 4");
  need(edge_rms_factor >= 1 && edge_rms_factor <= 10, "RegistrationOptions.edge_rms_factor in [1, 10]");
  need(relocate_rms_free_gain >= 0 && relocate_rms_free_gain <= 10, "RegistrationOptions.relocate_rms_free_gain in [0, 10]");
  need(principal_tolerance_deg > 0 && principal_tolerance_deg < 45,
       "RegistrationOptions.principal_tolerance_deg in (0, 45)");
}

Contour TransformPoints(const cv::Matx33d& T, const Contour& pts) {
  Contour out(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const double x = pts[i].x, y = pts[i].y;
    const double w = T(2, 0) * x + T(2, 1) * y + T(2, 2);
    const double iw = std::abs(w) > 1e-12 ? 1.0 / w : 1e12;
    out[i] = cv::Point2f(float((T(0, 0) * x + T(0, 1) * y + T(0, 2)) * iw),
                         float((T(1, 0) * x + T(1, 1) * y + T(1, 2)) * iw));
  }
  return out;
}

namespace {

using Model = RegistrationOptions::Model;
using Corr = std::vector<std::pair<cv::Point2f, cv::Point2f>>;

const char* ModelName(Model m) {
  switch (m) {
    case Model::kSimilarity: return "similarity";
    case Model::kAffine: return "affine";
    default: return "perspective";
  }
}

// ---- least-squares model fits (photo -> depth) ----------------------------

bool FitSimilarity(const Corr& c, cv::Matx33d* T) {
  if (c.size() < 2) return false;
  double mx = 0, my = 0, nx = 0, ny = 0;
  for (const auto& [p, q] : c) mx += p.x, my += p.y, nx += q.x, ny += q.y;
  const double n = double(c.size());
  mx /= n, my /= n, nx /= n, ny /= n;
  double a = 0, b = 0, ss = 0;
  for (const auto& [p, q] : c) {
    const double px = p.x - mx, py = p.y - my, qx = q.x - nx, qy = q.y - ny;
    a += px * qx + py * qy;
    b += px * qy - py * qx;
    ss += px * px + py * py;
  }
  if (!(ss > 1e-9)) return false;
  const double ca = a / ss, sb = b / ss;
  *T = cv::Matx33d(ca, -sb, nx - (ca * mx - sb * my), sb, ca, ny - (sb * mx + ca * my), 0, 0, 1);
  return std::isfinite(ca) && std::isfinite(sb) && (ca * ca + sb * sb) > 1e-12;
}

bool FitAffine(const Corr& c, cv::Matx33d* T) {
  if (c.size() < 3) return false;
  cv::Matx33d AtA = cv::Matx33d::zeros();
  cv::Matx32d AtB = cv::Matx32d::zeros();
  // centre for conditioning
  double mx = 0, my = 0;
  for (const auto& pq : c) mx += pq.first.x, my += pq.first.y;
  mx /= double(c.size()), my /= double(c.size());
  for (const auto& [p, q] : c) {
    const cv::Vec3d a(p.x - mx, p.y - my, 1.0);
    AtA += a * a.t();
    for (int r = 0; r < 3; ++r) AtB(r, 0) += a[r] * q.x, AtB(r, 1) += a[r] * q.y;
  }
  cv::Matx32d X;
  if (!cv::solve(AtA, AtB, X, cv::DECOMP_CHOLESKY)) return false;
  if (cv::determinant(AtA) < 1e-9 * std::pow(cv::trace(AtA), 3)) return false;
  // x' = X(0,0) (x - mx) + X(1,0) (y - my) + X(2,0)
  const cv::Matx33d M(X(0, 0), X(1, 0), X(2, 0), X(0, 1), X(1, 1), X(2, 1), 0, 0, 1);
  const cv::Matx33d C(1, 0, -mx, 0, 1, -my, 0, 0, 1);
  *T = M * C;
  return true;
}

bool FitHomography(const Corr& c, cv::Matx33d* T) {
  if (c.size() < 8) return false;
  std::vector<cv::Point2f> s, d;
  s.reserve(c.size()), d.reserve(c.size());
  for (const auto& [p, q] : c) s.push_back(p), d.push_back(q);
  cv::Mat H = cv::findHomography(s, d, 0);
  if (H.empty()) return false;
  H.convertTo(H, CV_64F);
  if (std::abs(H.at<double>(2, 2)) < 1e-12) return false;
  H /= H.at<double>(2, 2);
  *T = cv::Matx33d(H);
  return true;
}

bool Fit(Model m, const Corr& c, cv::Matx33d* T) {
  switch (m) {
    case Model::kSimilarity: return FitSimilarity(c, T);
    case Model::kAffine: return FitAffine(c, T);
    default: return FitHomography(c, T);
  }
}

// Local scale and rotation of T at point p (Jacobian), for plausibility checks.
bool LocalScaleRotation(const cv::Matx33d& T, cv::Point2f p, double* scale, double* rot_deg) {
  const double e = 1.0;
  const Contour q = TransformPoints(T, {p, p + cv::Point2f(float(e), 0), p + cv::Point2f(0, float(e))});
  const cv::Point2f dx = (q[1] - q[0]) / e, dy = (q[2] - q[0]) / e;
  const double det = double(dx.x) * dy.y - double(dx.y) * dy.x;
  if (!(det > 0)) return false;  // reflection or degenerate
  *scale = std::sqrt(det);
  *rot_deg = std::atan2(dx.y - dy.x, dx.x + dy.y) * 180.0 / CV_PI;
  return std::isfinite(*scale);
}

// ---- depth-side lookup: distance to / nearest point of / id of the nearest
// depth contour, on a raster of the depth contours ---------------------------

class DepthIndex {
 public:
  DepthIndex(const std::vector<Contour>& regions, double margin) {
    float x0 = std::numeric_limits<float>::max(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const auto& c : regions)
      for (const auto& p : c) x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x), y1 = std::max(y1, p.y);
    extent_ = cv::Rect2d(x0, y0, x1 - x0, y1 - y0);
    ox_ = x0 - margin, oy_ = y0 - margin;
    const double w = x1 - x0 + 2 * margin, h = y1 - y0 + 2 * margin;
    s_ = std::min(1.0, 3000.0 / std::max(w, h));
    const int W = int(std::ceil(w * s_)) + 2, H = int(std::ceil(h * s_)) + 2;
    cv::Mat img(H, W, CV_8U, cv::Scalar(255));
    cv::Mat ids(H, W, CV_32S, cv::Scalar(-1));
    for (size_t r = 0; r < regions.size(); ++r) {
      std::vector<cv::Point> pts;
      for (const auto& p : regions[r]) pts.emplace_back(int(std::lround((p.x - ox_) * s_)), int(std::lround((p.y - oy_) * s_)));
      const std::vector<std::vector<cv::Point>> poly{pts};
      cv::polylines(img, poly, true, cv::Scalar(0), 1, cv::LINE_8);
      cv::polylines(ids, poly, true, cv::Scalar(double(r)), 1, cv::LINE_8);
    }
    cv::distanceTransform(img, dist_, labels_, cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    double maxl = 0;
    cv::minMaxLoc(labels_, nullptr, &maxl);
    pos_.assign(size_t(maxl) + 1, cv::Point2f(0, 0));
    region_.assign(size_t(maxl) + 1, -1);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        if (img.at<uchar>(y, x) == 0) {
          const int l = labels_.at<int>(y, x);
          pos_[l] = cv::Point2f(float(x / s_ + ox_), float(y / s_ + oy_));
          region_[l] = ids.at<int>(y, x);
        }
  }
  // false when p is outside the raster
  bool Lookup(cv::Point2f p, float* d, int* region, cv::Point2f* nearest) const {
    const int x = int(std::lround((p.x - ox_) * s_)), y = int(std::lround((p.y - oy_) * s_));
    if (!(x >= 0 && y >= 0 && x < dist_.cols && y < dist_.rows)) return false;
    const int l = labels_.at<int>(y, x);
    *d = float(dist_.at<float>(y, x) / s_);
    *region = region_[l];
    *nearest = pos_[l];
    return true;
  }
  const cv::Rect2d& extent() const { return extent_; }

 private:
  double ox_ = 0, oy_ = 0, s_ = 1;
  cv::Rect2d extent_;
  cv::Mat dist_, labels_;
  std::vector<cv::Point2f> pos_;
  std::vector<int> region_;
};

struct Region {
  int index = -1;       // in the caller's vector
  ShapeDescriptor desc;  // full descriptor (points = N resampled points)
  Contour poly;          // contour simplified to 0.5 px, for exact closest points
  cv::Point2f centroid;
};

// Exact closest point of a closed polyline to p.
cv::Point2f ClosestOnPolyline(const Contour& poly, cv::Point2f p, double* dist) {
  double best = std::numeric_limits<double>::max();
  cv::Point2f bp = p;
  for (size_t i = 0, n = poly.size(); i < n; ++i) {
    const cv::Point2f a = poly[i], b = poly[(i + 1) % n];
    const cv::Point2f ab = b - a;
    const double l2 = ab.dot(ab);
    double t = l2 > 0 ? (p - a).dot(ab) / l2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    const cv::Point2f q(float(a.x + t * ab.x), float(a.y + t * ab.y));
    const double d = cv::norm(p - q);
    if (d < best) best = d, bp = q;
  }
  *dist = best;
  return bp;
}

struct Evaluation {
  std::vector<std::pair<int, int>> pairs;  // (photo, depth) positions in the Region vectors
  Corr corr;                               // raster closest points, within tol
  double mean_dist = 0;
  int count() const { return int(pairs.size()); }
};

class Verifier {
 public:
  Verifier(const std::vector<Region>& photo, const std::vector<Region>& depth, const DepthIndex& index,
           const RegistrationOptions& opt)
      : photo_(photo), depth_(depth), index_(index), opt_(opt) {}

  Evaluation Evaluate(const cv::Matx33d& T, double tol) const {
    struct Cand { int p, d, votes; double dist; };
    std::vector<Cand> cands;
    std::vector<std::pair<int, int>> votes;  // (depth region, votes)
    std::vector<double> dsum;
    for (int p = 0; p < int(photo_.size()); ++p) {
      const Contour proj = TransformPoints(T, photo_[p].desc.points);
      votes.clear(), dsum.clear();
      for (const auto& q : proj) {
        float d; int r; cv::Point2f nq;
        if (!index_.Lookup(q, &d, &r, &nq) || d > tol || r < 0) continue;
        size_t k = 0;
        while (k < votes.size() && votes[k].first != r) ++k;
        if (k == votes.size()) votes.emplace_back(r, 0), dsum.push_back(0);
        ++votes[k].second, dsum[k] += d;
      }
      if (votes.empty()) continue;
      size_t bk = 0;
      for (size_t k = 1; k < votes.size(); ++k) if (votes[k].second > votes[bk].second) bk = k;
      const int n = int(proj.size());
      if (votes[bk].second < opt_.inlier_fraction * n) continue;
      const int d = votes[bk].first;
      const double area = SignedArea(proj);
      if (!(area > 0)) continue;
      const double ratio = area / std::max(depth_[d].desc.area, 1e-9);
      if (ratio > opt_.max_area_ratio || ratio < 1.0 / opt_.max_area_ratio) continue;
      cands.push_back({p, d, votes[bk].second, dsum[bk] / votes[bk].second});
    }
    std::sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) {
      return a.votes > b.votes || (a.votes == b.votes && (a.dist < b.dist || (a.dist == b.dist && a.p < b.p)));
    });
    Evaluation e;
    std::vector<char> taken(depth_.size(), 0);
    double sum = 0;
    for (const Cand& c : cands) {
      if (taken[c.d]) continue;
      taken[c.d] = 1;
      e.pairs.emplace_back(c.p, c.d);
      sum += c.dist;
      const Contour proj = TransformPoints(T, photo_[c.p].desc.points);
      for (size_t j = 0; j < proj.size(); ++j) {
        float d; int r; cv::Point2f nq;
        if (index_.Lookup(proj[j], &d, &r, &nq) && d <= tol && r == c.d) e.corr.emplace_back(photo_[c.p].desc.points[j], nq);
      }
    }
    e.mean_dist = e.pairs.empty() ? 0 : sum / double(e.pairs.size());
    return e;
  }

  // Exact closest-point correspondences for fixed region pairs; trimmed.
  Corr ClosestPoints(const cv::Matx33d& T, const std::vector<std::pair<int, int>>& pairs, double max_dist,
                     double* rms) const {
    Corr c;
    double ss = 0;
    for (const auto& [p, d] : pairs) {
      const Contour& src = photo_[p].desc.points;
      const Contour proj = TransformPoints(T, src);
      for (size_t j = 0; j < proj.size(); ++j) {
        double dist;
        const cv::Point2f q = ClosestOnPolyline(depth_[d].poly, proj[j], &dist);
        if (dist <= max_dist) c.emplace_back(src[j], q), ss += dist * dist;
      }
    }
    *rms = c.empty() ? 1e9 : std::sqrt(ss / double(c.size()));
    return c;
  }

  // Inputs mapped into the other side's extent: (photo regions whose projected
  // centroid lies in the depth extent, depth regions inside the hull of the
  // projected photo regions).
  std::pair<int, int> Overlap(const cv::Matx33d& T) const {
    const cv::Rect2d& ext = index_.extent();
    int np = 0;
    Contour all;
    for (const auto& r : photo_) {
      const Contour c = TransformPoints(T, {r.centroid});
      if (ext.contains(cv::Point2d(c[0]))) ++np;
      const Contour proj = TransformPoints(T, r.desc.points);
      all.insert(all.end(), proj.begin(), proj.end());
    }
    int nd = 0;
    if (all.size() >= 3) {
      Contour hull;
      cv::convexHull(all, hull);
      for (const auto& r : depth_)
        if (cv::pointPolygonTest(hull, r.centroid, false) >= 0) ++nd;
    }
    return {np, nd};
  }

 private:
  const std::vector<Region>& photo_;
  const std::vector<Region>& depth_;
  const DepthIndex& index_;
  const RegistrationOptions& opt_;
};

std::vector<Region> Prepare(const std::vector<Contour>& in, const RegistrationOptions& opt) {
  std::vector<Region> out;
  for (int i = 0; i < int(in.size()); ++i) {
    const Contour& c = in[i];
    if (c.size() < 3) continue;
    bool finite = true;
    for (const auto& p : c) finite = finite && std::isfinite(p.x) && std::isfinite(p.y);
    if (!finite || std::abs(SignedArea(c)) < std::max(opt.min_region_area, 1e-6)) continue;
    Region r;
    r.index = i;
    r.desc = DescribeContour(c, opt.shape);
    if (r.desc.empty()) continue;
    r.desc.region = i;
    cv::approxPolyDP(c, r.poly, 0.5, true);
    if (r.poly.size() < 3) r.poly = c;
    cv::Point2f m(0, 0);
    for (const auto& p : r.desc.points) m += p;
    r.centroid = m * (1.0f / float(r.desc.points.size()));
    out.push_back(std::move(r));
  }
  return out;
}

struct Hypothesis {
  int p, dd;     // photo region position, depth descriptor position
  int shift;
  double rank, cost;
};

// The similarity one region pair proposes (its descriptor points, aligned at
// `shift`), if plausible: scale within the options' range, and the pair
// itself aligned (RMS of the fit vs the depth region's size).
bool SeedTransform(const Region& photo, const ShapeDescriptor& ddsc, int shift, const RegistrationOptions& opt,
                   cv::Matx33d* T, double* scale, double* rot) {
  const ShapeDescriptor& pdsc = photo.desc;
  const int n = int(pdsc.points.size());
  Corr seed;
  for (int j = 0; j < n; ++j) seed.emplace_back(pdsc.points[j], ddsc.points[(j + shift) % n]);
  if (!FitSimilarity(seed, T)) return false;
  if (!LocalScaleRotation(*T, photo.centroid, scale, rot)) return false;
  if (*scale < opt.min_scale || *scale > opt.max_scale) return false;
  double ss = 0;
  const Contour proj = TransformPoints(*T, pdsc.points);
  for (int j = 0; j < n; ++j) ss += std::pow(cv::norm(proj[j] - seed[j].second), 2);
  return std::sqrt(ss / n) <= 0.08 * ddsc.scale + opt.inlier_px;
}

}  // namespace

// ---- principal directions (§7.2.4) ----------------------------------------

namespace {
std::optional<PrincipalDirections> DirectionsFromEdges(const cv::Mat& edges, double min_len) {
  std::vector<cv::Vec4i> lines;
  cv::HoughLinesP(edges, lines, 1, CV_PI / 180, 20, min_len, 3);
  if (lines.size() < 6) return std::nullopt;
  double h[36] = {0};
  for (const auto& l : lines) {
    const double dx = l[2] - l[0], dy = l[3] - l[1];
    double a = std::atan2(dy, dx) * 180.0 / CV_PI;
    a = std::fmod(a + 360.0, 180.0);
    h[std::min(35, int(a / 5.0))] += std::hypot(dx, dy);
  }
  const int b1 = int(std::max_element(h, h + 36) - h);
  const double total = std::accumulate(h, h + 36, 0.0);
  auto refine = [&](int b) {  // weighted mean of the 3 bins around the peak
    const double l = h[(b + 35) % 36], c = h[b], r = h[(b + 1) % 36];
    return std::fmod((b + 0.5) * 5.0 + 5.0 * (r - l) / std::max(l + c + r, 1e-9) + 180.0, 180.0);
  };
  int b2 = -1;
  for (int b = 0; b < 36; ++b) {
    const int dist = std::min(std::abs(b - b1), 36 - std::abs(b - b1));
    if (dist >= 9 && (b2 < 0 || h[b] > h[b2])) b2 = b;
  }
  // a distinct peak: clearly above the uniform level (36 bins)
  if (h[b1] < 3.0 * total / 36 || b2 < 0 || h[b2] < 1.5 * total / 36) return std::nullopt;
  return PrincipalDirections{refine(b1), refine(b2)};
}
}  // namespace

std::optional<PrincipalDirections> DetectPrincipalDirections(const cv::Mat& image) {
  if (image.empty()) return std::nullopt;
  cv::Mat gray = image;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  if (gray.depth() != CV_8U) gray.convertTo(gray, CV_8U);
  cv::Mat edges;
  cv::Canny(gray, edges, 50, 150);
  return DirectionsFromEdges(edges, std::max(10.0, 0.02 * std::max(image.cols, image.rows)));
}

std::optional<PrincipalDirections> DetectPrincipalDirections(const std::vector<Contour>& regions) {
  float x0 = std::numeric_limits<float>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const auto& c : regions)
    for (const auto& p : c) x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x), y1 = std::max(y1, p.y);
  if (!(x1 > x0 && y1 > y0)) return std::nullopt;
  const double s = std::min(1.0, 2000.0 / std::max(x1 - x0, y1 - y0));
  cv::Mat img(int((y1 - y0) * s) + 3, int((x1 - x0) * s) + 3, CV_8U, cv::Scalar(0));
  for (const auto& c : regions) {
    std::vector<cv::Point> pts;
    for (const auto& p : c) pts.emplace_back(int(std::lround((p.x - x0) * s)) + 1, int(std::lround((p.y - y0) * s)) + 1);
    cv::polylines(img, std::vector<std::vector<cv::Point>>{pts}, true, cv::Scalar(255), 1, cv::LINE_8);
  }
  return DirectionsFromEdges(img, 10.0);
}

// ---- registration ------------------------------------------------------------

// Largest relative change of the projective divisor w = h31 x + h32 y + h33
// between the centre of `r` and its corners: 0 for an affine map; a nadir
// photo's perspective changes it by a few per cent.
static double PerspectiveAmount(const cv::Matx33d& T, const cv::Rect2d& r) {
  const auto w = [&](double x, double y) { return T(2, 0) * x + T(2, 1) * y + T(2, 2); };
  const double wc = w(r.x + r.width / 2, r.y + r.height / 2);
  if (!(std::abs(wc) > 1e-12)) return std::numeric_limits<double>::infinity();
  double p = 0;
  for (const double x : {r.x, r.x + r.width})
    for (const double y : {r.y, r.y + r.height}) p = std::max(p, std::abs(w(x, y) / wc - 1));
  return p;
}

// Ratio of the larger to the smaller singular value of T's Jacobian at the
// centre of `r`: how much more T stretches one photo axis than the other
// there (1 for a similarity; infinity when degenerate).
static double Anisotropy(const cv::Matx33d& T, const cv::Rect2d& r) {
  const double x = r.x + r.width / 2, y = r.y + r.height / 2;
  const double w = T(2, 0) * x + T(2, 1) * y + T(2, 2);
  if (!(std::abs(w) > 1e-12)) return std::numeric_limits<double>::infinity();
  const double u = (T(0, 0) * x + T(0, 1) * y + T(0, 2)) / w, v = (T(1, 0) * x + T(1, 1) * y + T(1, 2)) / w;
  const cv::Matx22d J((T(0, 0) - u * T(2, 0)) / w, (T(0, 1) - u * T(2, 1)) / w, (T(1, 0) - v * T(2, 0)) / w,
                      (T(1, 1) - v * T(2, 1)) / w);
  cv::Vec2d sv;
  cv::SVD::compute(J, sv, cv::SVD::NO_UV);
  return sv[1] > 1e-12 ? sv[0] / sv[1] : std::numeric_limits<double>::infinity();
}

std::string NadirShape(const cv::Matx33d& T, const cv::Rect2d& r, const RegistrationOptions& opt) {
  if (opt.max_perspective > 0) {
    const double p = PerspectiveAmount(T, r);
    if (p > opt.max_perspective)
      return cv::format("needs a steep perspective (divisor changes by %.2f across the photo > %.2f)", p,
                        opt.max_perspective);
  }
  if (opt.max_anisotropy > 0) {
    const double a = Anisotropy(T, r);
    if (a > opt.max_anisotropy)
      return cv::format("stretches the photo %.2f times more along one axis than the other (> %.2f)", a,
                        opt.max_anisotropy);
  }
  return {};
}

// Largest distance, depth px, between where two transforms put the corners of `r`.
static double PoseGap(const cv::Matx33d& A, const cv::Matx33d& B, const cv::Rect2d& r) {
  double g = 0;
  for (const double x : {r.x, r.x + r.width})
    for (const double y : {r.y, r.y + r.height}) {
      const Contour p = {cv::Point2f(float(x), float(y))};
      g = std::max(g, double(cv::norm(TransformPoints(A, p)[0] - TransformPoints(B, p)[0])));
    }
  return g;
}

constexpr double kLeanAtBound = 0.9;  // share of EdgeEvidenceOptions::max_lean_px_per_m

// The image check of a transform (edge_evidence.h). The roofs are scored
// only when the edges alone fall short: they may then admit it.
static bool ImagePasses(const EdgeEvidence& ev, const cv::Matx33d& T, cv::Point2d lean, EdgeScore* e) {
  if (e->enough && e->contrast < ev.options().min_contrast) ev.ScoreRoofs(T, lean, e);
  return ev.Accepts(*e);
}

// The roofs of a final answer (with its lean): "" when they do not refuse it,
// else why. Fills e's roof fields either way.
static std::string RoofVeto(const EdgeEvidence& ev, const cv::Matx33d& T, cv::Point2d lean, EdgeScore* e) {
  ev.ScoreRoofs(T, lean, e);
  if (ev.Accepts(*e)) return {};
  return cv::format("its outlines do not set roofs apart from the ground (roof contrast %.2f < %.2f over %d outlines)",
                    e->roof_contrast, ev.options().roof_veto, e->roof_regions);
}

// An answer refined with the photo's lean (T3, lean) replaces the accepted
// one, whose image check gave `accepted`, when it passes the same checks:
// outlines on edges (no fewer), the perspective bound, a proper transform
// at `at`; and when the lean is not at its bound (kLeanAtBound). Its image
// check goes to *e3.
static bool LeanAnswerPasses(const EdgeEvidence& ev, const cv::Matx33d& T3, cv::Point2d lean, const EdgeScore& accepted,
                             const RegistrationOptions& opt, const cv::Rect2d& extent, cv::Point2f at, EdgeScore* e3) {
  if (lean == cv::Point2d()) return false;
  // A lean pressed against its bound is the bound, not an estimate: on true
  // orthophotos (classic scenes) such leans fitted residue, 0.4 -> 7.9 px.
  if (std::hypot(lean.x, lean.y) >= kLeanAtBound * ev.options().max_lean_px_per_m) return false;
  *e3 = ev.Evaluate(T3, lean);
  double scale, rot;
  return ImagePasses(ev, T3, lean, e3) && e3->regions_on_edges >= accepted.regions_on_edges &&
         NadirShape(T3, extent, opt).empty() &&
         LocalScaleRotation(T3, at, &scale, &rot);
}

// The lean answer (T3, lean; image check e3) against the lean-free one (T,
// image check e): its roofs must stand apart at least `min_ratio` as much.
// Both scored over at least min_roof_veto_regions outlines, else (and with
// min_ratio 0) no verdict: true. The lean has two parameters of its own that
// the edges alone can spend on a lean traded for a translation; the roofs,
// an evidence the refinement did not maximise, then drop.
static bool LeanKeepsRoofs(const EdgeEvidence& ev, const cv::Matx33d& T, EdgeScore e, const cv::Matx33d& T3,
                           cv::Point2d lean, double min_ratio, EdgeScore* e3) {
  if (min_ratio <= 0) return true;
  ev.ScoreRoofs(T, {}, &e);
  ev.ScoreRoofs(T3, lean, e3);
  const int need = ev.options().min_roof_veto_regions;
  if (e.roof_regions < need || e3->roof_regions < need) return true;
  return e3->roof_contrast >= min_ratio * e.roof_contrast;
}

// The region pairs refitted with the photo's lean: a conventional
// orthophoto shows a roof h metres high h * lean from its footprint, so a
// transform fitted to roofs of different heights carries their mean
// displacement and, where heights vary across the photo, a tilt and a
// scale error too; refinement from there can settle with a lean that
// compensates them (issue 21: dense near misses). Each contour point p of
// a paired photo region and its closest depth outline point q (at `T`)
// give A p - h l = q, with h the depth region's height: an affine A and
// the lean l by linear least squares. False when the pairs' heights do not
// spread by the lean's minimum, or the lean leaves its bound.
static bool JointLeanFit(const std::vector<Region>& depth,
                         const std::vector<std::pair<int, int>>& pairs, const Verifier& verifier,
                         const cv::Matx33d& T, double max_dist, const EdgeEvidence& ev, cv::Matx33d* out,
                         cv::Point2d* lean) {
  if (!ev.has_heights() || ev.options().max_lean_px_per_m <= 0) return false;
  float h0 = std::numeric_limits<float>::infinity(), h1 = -h0;
  std::vector<cv::Vec<double, 9>> rows;  // 8 coefficients and the right-hand side
  for (const auto& pr : pairs) {
    const float h = ev.height(size_t(depth[size_t(pr.second)].index));
    double rms;
    const Corr c = verifier.ClosestPoints(T, {pr}, max_dist, &rms);
    if (c.empty()) continue;
    h0 = std::min(h0, h), h1 = std::max(h1, h);
    for (const auto& [p, q] : c) {
      rows.push_back({p.x, p.y, 1, 0, 0, 0, -double(h), 0, q.x});
      rows.push_back({0, 0, 0, p.x, p.y, 1, 0, -double(h), q.y});
    }
  }
  if (rows.size() < 16 || !(h1 - h0 >= ev.options().min_lean_height_spread_m)) return false;
  cv::Mat A(int(rows.size()), 8, CV_64F), b(int(rows.size()), 1, CV_64F);
  for (int i = 0; i < A.rows; ++i) {
    for (int k = 0; k < 8; ++k) A.at<double>(i, k) = rows[size_t(i)][k];
    b.at<double>(i) = rows[size_t(i)][8];
  }
  cv::Mat x;
  if (!cv::solve(A, b, x, cv::DECOMP_SVD)) return false;
  const cv::Point2d l(x.at<double>(6), x.at<double>(7));
  if (!(std::hypot(l.x, l.y) < ev.options().max_lean_px_per_m)) return false;
  *out = cv::Matx33d(x.at<double>(0), x.at<double>(1), x.at<double>(2), x.at<double>(3), x.at<double>(4),
                     x.at<double>(5), 0, 0, 1);
  *lean = l;
  return true;
}

// The largest mean gap (depth px, over the outlines in view) between the
// answer T (with its lean) and a pose refined from one of 8 perspective
// perturbations that scores at least the answer's contrast (see
// RegistrationOptions::ambiguity_px).
double AmbiguityGap(const EdgeEvidence& ev, const cv::Matx33d& T, cv::Point2d lean,
                    const RegistrationOptions& opt, const cv::Rect2d& extent) {
  const double L = std::max(extent.width, extent.height);
  if (!(L > 0)) return 0;
  const double cx = extent.x + extent.width / 2, cy = extent.y + extent.height / 2;
  const cv::Matx33d to_centre(1, 0, -cx, 0, 1, -cy, 0, 0, 1), from_centre(1, 0, cx, 0, 1, cy, 0, 0, 1);
  const double c0 = ev.Evaluate(T, lean).contrast;
  const double step = opt.ambiguity_perspective / L;
  double gap = 0;
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j) {
      if (i == 0 && j == 0) continue;
      const cv::Matx33d P(1, 0, 0, 0, 1, 0, i * step, j * step, 1);
      cv::Point2d l = lean;
      const cv::Matx33d Tr =
          ev.Refine(T * from_centre * P * to_centre, true, true, nullptr, lean == cv::Point2d() ? nullptr : &l);
      if (ev.Evaluate(Tr, l).contrast >= c0) gap = std::max(gap, ev.MeanGap(T, Tr));
    }
  return gap;
}

// The single-pair route (see RegistrationOptions::single_pair_route). Fills
// *res and returns "" on success, else the reason.
static std::string SinglePairRoute(const std::vector<Region>& photo, const std::vector<Region>& depth,
                                   const std::vector<ShapeDescriptor>& ddesc, const std::vector<int>& ddesc_region,
                                   const std::vector<Hypothesis>& hyps, const Verifier& verifier,
                                   const RegistrationOptions& opt, const EdgeEvidence& ev, const cv::Rect2d& extent,
                                   Registration* res) {
  struct Pose {
    cv::Matx33d T;
    EdgeScore e;
    size_t h = 0;
    double z = 0;
  };
  // A layout, not a shape: many outlines in view, on edges. The score is
  // the contrast's excess over random placement (1) weighted by the outline
  // samples in view, so that a pose showing two outlines on strong edges
  // does not beat one showing twenty on edges.
  auto zraw = [](const EdgeScore& e) { return e.enough ? (e.contrast - 1.0) * std::sqrt(double(e.points)) : 0.0; };
  auto zscore = [&](const EdgeScore& e) { return e.regions >= opt.single_pair_min_outlines ? zraw(e) : 0.0; };
  std::vector<Pose> poses;
  int tried = 0;
  for (size_t i = 0; i < hyps.size() && tried < opt.max_hypotheses; ++i) {
    cv::Matx33d T;
    double scale, rot;
    if (!SeedTransform(photo[hyps[i].p], ddesc[hyps[i].dd], hyps[i].shift, opt, &T, &scale, &rot)) continue;
    ++tried;
    const EdgeScore e = ev.Evaluate(T, {}, 4);  // screening: every 4th outline sample
    if (e.contrast >= opt.single_pair_min_seed_contrast && zraw(e) > 0) poses.push_back({T, e, i, zraw(e)});
  }
  if (poses.empty()) return "single-pair route: no region pair's transform puts outlines on photo edges";
  std::stable_sort(poses.begin(), poses.end(), [](const Pose& a, const Pose& b) { return a.z > b.z; });
  const double distinct = opt.single_pair_distinct_px;
  // the few best distinct poses, snapped onto the edges (similarity, coarse)
  std::vector<Pose> top;
  for (const Pose& q : poses) {
    if (int(top.size()) >= opt.single_pair_poses) break;
    bool same = false;
    for (const Pose& t : top) same = same || PoseGap(q.T, t.T, extent) < distinct;
    if (!same) top.push_back(q);
  }
  for (Pose& t : top) {
    t.T = ev.Refine(t.T, false, /*sharp=*/false);
    t.e = ev.Evaluate(t.T);
    t.z = zraw(t.e);
  }
  // The answer: the best pose with enough outlines in view. Its rival: the
  // best clearly different pose with any number (a pose that puts two
  // outlines on strong edges is evidence that such edges are everywhere).
  size_t bi = 0;
  for (size_t k = 1; k < top.size(); ++k)
    if (zscore(top[k].e) > zscore(top[bi].e)) bi = k;
  const Pose& best = top[bi];
  double runner = 0;
  for (size_t k = 0; k < top.size(); ++k)
    if (k != bi && PoseGap(top[k].T, best.T, extent) >= distinct) runner = std::max(runner, top[k].z);
  if (zscore(best.e) <= 0) return "single-pair route: no pose puts enough outlines in view on photo edges";
  const double c1 = best.e.contrast;
  const double confidence = best.z > 0 ? std::clamp((best.z - runner) / best.z, 0.0, 1.0) : 0.0;
  const EdgeScore& e1 = best.e;
  const std::string what = cv::format("single-pair route: outline edge contrast %.2f, score %.1f, runner-up %.1f, "
                                      "confidence %.2f, %d of %d outlines on edges",
                                      c1, best.z, runner, confidence, e1.regions_on_edges, e1.regions);
  // A layout, not a shape: many outlines in view, most of them on edges,
  // and no other pose nearly as good.
  if (!ev.Accepts(e1) || e1.regions < opt.single_pair_min_outlines ||
      e1.regions_on_edges < opt.single_pair_min_on_edges * e1.regions || confidence < opt.single_pair_min_confidence)
    return what;
  const bool persp = opt.model == RegistrationOptions::Model::kPerspective || opt.model == RegistrationOptions::Model::kAuto;
  cv::Matx33d T = ev.Refine(best.T, persp);
  EdgeScore e = ev.Evaluate(T);
  if (!ImagePasses(ev, T, {}, &e) || e.regions_on_edges < opt.single_pair_min_on_edges * e.regions)
    return what + cv::format("; refined outlines not on edges (contrast %.2f, %d of %d)", e.contrast, e.regions_on_edges,
                             e.regions);
  if (const std::string shape = NadirShape(T, extent, opt); !shape.empty()) return what + "; " + shape;
  double scale, rot;
  if (!LocalScaleRotation(T, photo[hyps[best.h].p].centroid, &scale, &rot))
    return what + "; refined transform is degenerate or reflecting";
  // the lean, last, as on the region route
  cv::Point2d lean;
  const cv::Matx33d T3 = ev.Refine(best.T, persp, true, nullptr, &lean);
  EdgeScore e3;
  if (LeanAnswerPasses(ev, T3, lean, e, opt, extent, photo[hyps[best.h].p].centroid, &e3))
    T = T3, e = e3, res->lean_px_per_m = lean;
  // The roof veto, and then the roofs whatever the edges (see
  // RegistrationOptions::single_pair_route): "" when the pose passes.
  auto roofs = [&](const cv::Matx33d& P, cv::Point2d l, EdgeScore* s) -> std::string {
    if (std::string veto = RoofVeto(ev, P, l, s); !veto.empty()) return veto;
    const EdgeEvidenceOptions& eo = ev.options();
    if (s->roof_regions < eo.min_roof_veto_regions || eo.roof_veto <= 0 || s->roof_contrast >= eo.roof_veto) return {};
    return cv::format("one region pair needs roofs set apart from the ground (roof contrast %.2f < %.2f over %d "
                      "outlines)",
                      s->roof_contrast, eo.roof_veto, s->roof_regions);
  };
  if (const std::string veto = roofs(T, res->lean_px_per_m, &e); !veto.empty()) {
    res->lean_px_per_m = {};
    return what + "; " + veto;
  }
  if (persp && opt.ambiguity_px > 0) {
    res->ambiguity_px = AmbiguityGap(ev, T, res->lean_px_per_m, opt, extent);
    if (res->ambiguity_px > opt.ambiguity_px) {
      const std::string why = what + cv::format("; not determined to %.0f px: an equally good pose lies %.1f px away",
                                                opt.ambiguity_px, res->ambiguity_px);
      res->lean_px_per_m = {};
      return why;
    }
  }
  {  // the accepted answer relocated, as on the region route
    const EdgeEvidence::Relocation rl = ev.Relocate(T, res->lean_px_per_m, persp);
    EdgeScore er = rl.edge;
    if (rl.moved && NadirShape(rl.photo_to_depth, extent, opt).empty() &&
        roofs(rl.photo_to_depth, rl.lean, &er).empty())
      T = rl.photo_to_depth, e = er, res->lean_px_per_m = rl.lean, res->relocated_px = rl.moved_px;
  }
  // region pairs consistent with the answer, for the correspondences
  const double tol = opt.inlier_px * std::max(1.0, scale);
  Evaluation pairs = verifier.Evaluate(T, tol);
  if (pairs.pairs.empty()) pairs.pairs.emplace_back(hyps[best.h].p, ddesc_region[size_t(hyps[best.h].dd)]);
  res->ok = true;
  res->photo_to_depth = T;
  res->model = persp ? "perspective" : "similarity";
  res->edge = e;
  res->route = "single-pair";
  res->route_confidence = confidence;
  res->correspondences = verifier.ClosestPoints(T, pairs.pairs, 2 * tol, &res->rms_px);
  res->region_matches.clear();
  for (const auto& [p, d] : pairs.pairs) {
    RegionMatch m;
    m.a = photo[size_t(p)].index, m.b = depth[size_t(d)].index;
    res->region_matches.push_back(m);
  }
  res->reason = what + cv::format(", %d region pairs agree", int(pairs.pairs.size()));
  return {};
}

Registration RegisterContours(const std::vector<Contour>& photo_regions, const std::vector<Contour>& depth_regions,
                              const RegistrationOptions& opt, const EdgeEvidence* evidence) {
  opt.Check();
  Registration res;
  Timer timer;
  const std::vector<Region> photo = Prepare(photo_regions, opt);
  // The photo's extent, as far as its regions show it (for the perspective check).
  cv::Rect2d photo_extent;
  {
    float x0 = std::numeric_limits<float>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    for (const auto& c : photo_regions)
      for (const auto& q : c) {
        x0 = std::min(x0, q.x), y0 = std::min(y0, q.y);
        x1 = std::max(x1, q.x), y1 = std::max(y1, q.y);
      }
    if (x1 >= x0 && y1 >= y0) photo_extent = cv::Rect2d(x0, y0, x1 - x0, y1 - y0);
  }
  const std::vector<Region> depth = Prepare(depth_regions, opt);
  if (photo.empty() || depth.empty()) {
    res.reason = std::string("no registration found: no usable ") + (photo.empty() ? "photo" : "depth") +
                 " regions (need closed contours of >= 3 points and area >= min_region_area)";
    res.match_ms = timer.ElapsedMs();
    return res;
  }
  // image evidence is independent support: one region pair fewer will do
  const int min_regions = evidence ? std::min(opt.min_regions, opt.min_regions_with_evidence) : opt.min_regions;
  const double min_inlier_ratio =
      evidence ? std::min(opt.min_inlier_ratio, opt.min_inlier_ratio_with_evidence) : opt.min_inlier_ratio;
  // (the single-pair route needs one photo region, and outlines to judge it by)
  const bool single_pair_possible =
      evidence && opt.single_pair_route && int(depth.size()) >= opt.single_pair_min_outlines;
  if (int(std::min(photo.size(), depth.size())) < min_regions && !single_pair_possible) {
    res.reason = "no registration found: fewer regions than min_regions (" + std::to_string(photo.size()) +
                 " photo, " + std::to_string(depth.size()) + " depth)";
    res.match_ms = timer.ElapsedMs();
    return res;
  }

  // 1. depth descriptors: full + partial
  std::vector<ShapeDescriptor> ddesc;
  std::vector<int> ddesc_region;  // position in `depth`
  for (int d = 0; d < int(depth.size()); ++d) {
    ddesc.push_back(depth[d].desc), ddesc_region.push_back(d);
    if (opt.partial_descriptors)
      for (auto& pd : DescribePartials(depth_regions[depth[d].index], opt.shape, opt.partial_min_corners,
                                       opt.max_partials_per_region)) {
        pd.region = depth[d].index;
        ddesc.push_back(std::move(pd)), ddesc_region.push_back(d);
      }
  }

  // 2. matching: every depth descriptor against every photo region
  const int P = int(photo.size());
  cv::Mat full_cost(P, int(depth.size()), CV_64F, cv::Scalar(1.0));  // photo x depth, full descriptors
  std::vector<Hypothesis> hyps;
  std::vector<std::vector<double>> costs(P);
  for (int dd = 0; dd < int(ddesc.size()); ++dd) {
    std::vector<std::pair<double, int>> best;  // (cost, photo)
    for (int p = 0; p < P; ++p) {
      costs[p] = ShiftCosts(photo[p].desc, ddesc[dd]);
      const double c = *std::min_element(costs[p].begin(), costs[p].end());
      if (!ddesc[dd].partial) full_cost.at<double>(p, ddesc_region[dd]) = c;
      best.emplace_back(c, p);
    }
    std::sort(best.begin(), best.end());
    const double c0 = best[0].first, c1 = best.size() > 1 ? best[1].first : 1.0;
    for (int k = 0; k < std::min(opt.candidates_per_region, P); ++k) {
      const auto [c, p] = best[k];
      double rank = k == 0 ? c / std::max(c1, 1e-9) : c / std::max(c0, 1e-9);
      // partial descriptors enlarge the search space (§7.2.3): their pairs
      // are tried after the distinctive full-contour pairs
      if (ddesc[dd].partial) rank += opt.partial_rank_penalty;
      for (const ShiftCost& s : BestShifts(costs[p], opt.shifts_per_pair)) hyps.push_back({p, dd, s.shift, rank, s.cost});
    }
  }
  std::stable_sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) {
    return a.rank < b.rank || (a.rank == b.rank && a.cost < b.cost);
  });
  if (int(hyps.size()) > opt.max_hypotheses) {  // top half by rank, the rest sampled (seeded)
    const size_t keep = size_t(opt.max_hypotheses / 2);
    std::mt19937_64 rng(opt.seed);
    std::shuffle(hyps.begin() + keep, hyps.end(), rng);
    hyps.resize(opt.max_hypotheses);
  }
  res.match_ms = timer.ElapsedMs();
  timer.Restart();

  // 3.-4. hypotheses + propagation
  const DepthIndex index(depth_regions.empty() ? std::vector<Contour>{} : [&] {
    std::vector<Contour> v;
    for (const auto& r : depth) v.push_back(depth_regions[r.index]);
    return v;
  }(), 2 * opt.inlier_px * std::max(1.0, opt.max_scale) + 2);
  const Verifier verifier(photo, depth, index, opt);
  const Model grow_model = opt.model == Model::kSimilarity ? Model::kSimilarity : Model::kAffine;

  std::vector<double> allowed_rot;  // principal-direction prediction of the rotation
  if (opt.use_principal_directions) {
    const auto pd_photo = DetectPrincipalDirections(photo_regions);
    const auto pd_depth = DetectPrincipalDirections(depth_regions);
    if (pd_photo && pd_depth)
      for (double base : {pd_depth->first_deg - pd_photo->first_deg, pd_depth->first_deg - pd_photo->second_deg})
        for (int k = 0; k < 4; ++k) allowed_rot.push_back(base + 90.0 * k);
  }
  auto rotation_allowed = [&](double rot) {
    for (double a : allowed_rot) {
      double d = std::fmod(std::abs(rot - a), 360.0);
      d = std::min(d, 360.0 - d);
      if (d <= opt.principal_tolerance_deg) return true;
    }
    return false;
  };

  struct Candidate {
    Evaluation eval;
    cv::Matx33d T = cv::Matx33d::eye();
    bool from_restricted = false;
    double tol = 0;
    bool tried = false;
  };
  auto acceptable = [&](const Evaluation& e, const cv::Matx33d& T, double* ratio) {
    const auto [np, nd] = verifier.Overlap(T);
    *ratio = double(e.count()) / double(std::max(1, std::min(np, nd)));
    return e.count() >= min_regions && *ratio >= min_inlier_ratio;
  };
  // The few best distinct consistent sets (largest first); a set that shares
  // half of its pairs with a kept one is the same solution — the better stays.
  std::vector<Candidate> cands;
  constexpr int kMaxCandidates = 4;
  auto offer = [&](Candidate c) {
    auto better = [](const Evaluation& a, const Evaluation& b) {
      return a.count() > b.count() || (a.count() == b.count() && a.mean_dist < b.mean_dist);
    };
    for (auto& k : cands) {
      int shared = 0;
      for (const auto& pr : c.eval.pairs)
        shared += std::find(k.eval.pairs.begin(), k.eval.pairs.end(), pr) != k.eval.pairs.end();
      if (2 * shared >= std::min(c.eval.count(), k.eval.count())) {
        if (!k.tried && better(c.eval, k.eval)) k = std::move(c);
        return;
      }
    }
    cands.push_back(std::move(c));
    std::stable_sort(cands.begin(), cands.end(), [&](const Candidate& a, const Candidate& b) { return better(a.eval, b.eval); });
    if (int(cands.size()) > kMaxCandidates) cands.pop_back();
  };
  auto explained = [&](int p, int d) {
    for (const auto& k : cands)
      if (std::find(k.eval.pairs.begin(), k.eval.pairs.end(), std::make_pair(p, d)) != k.eval.pairs.end()) return true;
    return false;
  };
  const int min_side = int(std::min(photo.size(), depth.size()));
  int best_count = 0;
  double best_ratio = 0;

  // Search from hypothesis `next` of `pass` until the list is exhausted or a
  // strong consistent set is found (then stop early). Returns false when exhausted.
  size_t next = 0;
  int pass = allowed_rot.empty() ? 1 : 0;
  auto search = [&]() {
    for (; pass < 2; ++pass, next = 0) {
      for (; next < hyps.size() && res.hypotheses < opt.max_hypotheses; ++next) {
        const Hypothesis& h = hyps[next];
        const int d = ddesc_region[h.dd];
        const ShapeDescriptor& ddsc = ddesc[h.dd];
        cv::Matx33d T;
        double scale, rot;
        if (!SeedTransform(photo[h.p], ddsc, h.shift, opt, &T, &scale, &rot)) continue;
        if (!allowed_rot.empty() && rotation_allowed(rot) != (pass == 0)) continue;
        if (explained(h.p, d)) continue;  // already part of a kept consistent set
        ++res.hypotheses;
        // tolerances are in depth px; photo-side noise grows with the scale
        const double tol = opt.inlier_px * std::max(1.0, scale);
        Evaluation e;
        std::vector<std::pair<int, int>> prev;
        for (int it = 0; it < 8; ++it) {
          e = verifier.Evaluate(T, it == 0 ? 2 * tol : tol);
          if (e.count() == 0) break;
          const Model m = e.count() >= 3 ? grow_model : Model::kSimilarity;
          cv::Matx33d Tn;
          if (!Fit(m, e.corr, &Tn)) break;
          T = Tn;
          if (it > 0 && e.pairs == prev) break;
          prev = e.pairs;
        }
        e = verifier.Evaluate(T, tol);
        double ratio = 0;
        const bool acc = acceptable(e, T, &ratio);
        if (e.count() > best_count) best_count = e.count(), best_ratio = ratio;
        if (!acc) continue;
        const int count = e.count();
        offer(Candidate{std::move(e), T, pass == 0, tol, false});
        if (ratio >= 0.6 && count >= std::max(2 * opt.min_regions, min_side / 3)) { ++next; return true; }
      }
      if (pass == 0) {  // principal-direction pass over: try its candidates first
        ++pass, next = 0;
        return true;
      }
    }
    return false;
  };

  // 6. refinement per model (ICP on exact closest contour points), model
  // choice, final checks. Fills res on success, returns a reason on failure.
  struct Fitted { Model m; cv::Matx33d T; double rms; bool ok; };
  auto finish = [&](const Candidate& cand) -> std::string {
    const double tol = cand.tol;
    auto refine = [&](Model m, cv::Matx33d T, const std::vector<std::pair<int, int>>& pairs) {
      double rms = 1e9;
      bool ok = true;
      for (int it = 0; it < 12; ++it) {
        Corr c = verifier.ClosestPoints(T, pairs, 2 * tol, &rms);
        // trim the worst (closest point on the wrong edge near corners)
        std::vector<double> dists;
        for (const auto& [p, q] : c) dists.push_back(cv::norm(TransformPoints(T, {p})[0] - q));
        if (dists.size() < 8) { ok = false; break; }
        std::vector<double> sorted = dists;
        std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
        const double cut = std::max(3.0 * sorted[sorted.size() / 2], 1.0);
        Corr kept;
        for (size_t i = 0; i < c.size(); ++i) if (dists[i] <= cut) kept.push_back(c[i]);
        cv::Matx33d Tn;
        if (!Fit(m, kept, &Tn)) { ok = false; break; }
        const double change = cv::norm(cv::Mat(Tn - T));
        T = Tn;
        if (change < 1e-6) break;
      }
      verifier.ClosestPoints(T, pairs, 2 * tol, &rms);
      return Fitted{m, T, rms, ok};
    };
    std::vector<std::pair<int, int>> pairs = cand.eval.pairs;
    const std::vector<Model> models = opt.model == Model::kAuto
        ? std::vector<Model>{Model::kSimilarity, Model::kAffine, Model::kPerspective}
        : std::vector<Model>{opt.model};
    std::vector<Fitted> fits;
    int chosen = -1;
    cv::Matx33d start = cand.T;
    for (int round = 0; round < 4; ++round) {
      fits.clear();
      for (Model m : models) fits.push_back(refine(m, start, pairs));
      // kAuto: the simplest model unless a more complex one lowers the RMS by
      // >= 10 % and 0.1 px; affine needs >= 4 region pairs, perspective >= 6
      chosen = -1;
      int most_accurate = -1;
      for (int i = 0; i < int(fits.size()); ++i) {
        if (!fits[i].ok) continue;
        if (most_accurate < 0 || fits[i].rms < fits[most_accurate].rms) most_accurate = i;
        if (opt.model == Model::kAuto && ((fits[i].m == Model::kAffine && int(pairs.size()) < 4) ||
                                          (fits[i].m == Model::kPerspective && int(pairs.size()) < opt.perspective_min_pairs)))
          continue;
        // the perspective model (the camera's) needs only to fit no worse;
        // the affine one must clearly beat the similarity
        const bool persp = fits[i].m == Model::kPerspective;
        if (chosen < 0 || (persp && fits[i].rms <= fits[chosen].rms) ||
            (fits[i].rms < 0.9 * fits[chosen].rms && fits[i].rms < fits[chosen].rms - 0.1))
          chosen = i;
      }
      if (chosen < 0) break;
      // propagate with the most accurate fit: the set may grow (and allow a
      // richer model); stop when it does not
      Evaluation fin = verifier.Evaluate(fits[most_accurate].T, opt.grow_tolerance * tol);
      if (fin.count() <= int(pairs.size())) break;
      pairs = fin.pairs;
      start = fits[most_accurate].T;
    }
    if (chosen < 0) return "refinement of the consistent set failed";
    Fitted f = fits[chosen];
    double ratio;
    // Two ways to accept:
    //  - shapes alone: min_regions pairs, RMS <= max_rms_px (scaled; fewer
    //    pairs, tighter);
    //  - shapes + image: the outlines lie on photo edges (EdgeEvidence), with
    //    min_regions_with_evidence pairs and edge_rms_factor x the RMS bound.
    // The shapes-alone route is taken only without the image check, or when
    // require_image_evidence is off (photos whose roofs lean far, where the
    // image check fails while the shapes agree; it also accepts look-alike
    // sets far off, so it is not the default).
    const double support = std::clamp((double(pairs.size()) - 1.0) / 5.0, 0.5, 1.0);
    const double max_rms = support * opt.max_rms_px * tol / opt.inlier_px;
    const Fitted shape_fit = f;
    res.refused.push_back(f.T);  // removed again when this set is accepted
    const bool consistent = acceptable(Evaluation{pairs, {}, 0}, f.T, &ratio);
    const bool shape_ok =
        consistent && int(pairs.size()) >= opt.min_regions && ratio >= opt.min_inlier_ratio && f.rms <= max_rms;
    EdgeScore es;
    bool image_ok = false;
    struct LeanAnswer { cv::Matx33d T; cv::Point2d lean; };
    std::optional<LeanAnswer> lean_answer;
    if (evidence) {
      es = evidence->Evaluate(f.T);
      // a right but imprecise fit (few region pairs) puts the outlines beside
      // the edges: judge it after a small similarity correction (which cannot
      // put a wrong set of outlines on edges)
      // (the edges first, before and after the correction; the roofs only
      // when the edges fall short of both, at the corrected transform)
      bool passes = evidence->Accepts(es);
      if (es.enough && !passes && opt.edge_refine) {
        const cv::Matx33d T1 = evidence->Refine(f.T, false, /*sharp=*/false);
        EdgeScore es1 = evidence->Evaluate(T1);
        if (evidence->Accepts(es1) || ImagePasses(*evidence, T1, {}, &es1)) {
          es = es1, f.T = T1, passes = true;
          verifier.ClosestPoints(f.T, pairs, 2 * tol, &f.rms);
        } else {
          es.roof_regions = es1.roof_regions, es.roof_contrast = es1.roof_contrast;  // for the reason
        }
      } else if (es.enough && !passes) {
        passes = ImagePasses(*evidence, f.T, {}, &es);
      }
      image_ok = consistent && passes && f.rms <= opt.edge_rms_factor * max_rms;
    }
    res.edge = es;
    // With the image check on, every answer needs it: shapes alone accepted
    // 4-6 pairs of look-alike small rectangles (houses, sheds, pools) with
    // the photo squeezed onto a patch of the depth, 120-850 px off, whose
    // outlines were not on photo edges (contrast 0.9-1.6; issue 21).
    const bool accepted = evidence && opt.require_image_evidence ? image_ok : (shape_ok || image_ok);
    if (!accepted) {
      if (consistent && evidence && !es.enough && f.rms <= opt.edge_rms_factor * max_rms)
        return cv::format("best consistent set (%d region pairs) puts too few depth outlines in the photo for "
                          "the image check (%d samples, need %d)",
                          int(pairs.size()), es.points, evidence->options().min_points);
      if (!consistent || !es.enough || f.rms > opt.edge_rms_factor * max_rms)
        return cv::format("best consistent set fails the checks (%d region pairs, ratio %.2f, RMS %.2f px > %.2f)",
                          int(pairs.size()), ratio, shape_fit.rms, max_rms);
      return cv::format("best consistent set fails the image check (%d region pairs, outline edge contrast %.2f < %.2f",
                        int(pairs.size()), es.contrast, evidence->options().min_contrast) +
             (es.roof_regions > 0 ? cv::format(", roof contrast %.2f over %d outlines)", es.roof_contrast, es.roof_regions)
                                  : std::string(")"));
    }
    if (!image_ok) {
      f = shape_fit;  // accepted on shapes alone: keep their fit
    } else if (opt.edge_refine) {
      const bool persp = opt.model == Model::kPerspective || opt.model == Model::kAuto;
      // outwards from the region pairs the transform was fitted on
      Corr cc = verifier.ClosestPoints(f.T, pairs, 2 * tol, &f.rms);
      std::vector<cv::Point2f> dp;
      for (const auto& pq : cc) dp.push_back(pq.second);
      const cv::Matx33d start_T = f.T;
      const cv::Matx33d T2 = dp.size() >= 3 ? evidence->RefineOutward(f.T, cv::boundingRect(dp), persp)
                                            : evidence->Refine(f.T, persp);
      if (persp && f.m != Model::kPerspective) f.m = Model::kPerspective;
      f.T = T2;
      verifier.ClosestPoints(f.T, pairs, 2 * tol, &f.rms);
      res.edge = evidence->Evaluate(f.T);
      // right near the matched regions but not across the overlap (a fit
      // of a few clustered regions extrapolated): most outlines in view
      // must lie on edges. The photo's edges did align globally (the image
      // route), so this is evidence against the set even if its shapes pass.
      const bool refined_passes = ImagePasses(*evidence, f.T, {}, &res.edge);
      const EdgeScore& e = res.edge;
      if (e.regions >= 8 && e.regions_on_edges < evidence->options().min_regions_on_edges * e.regions)
        return cv::format("best consistent set fits only part of the photo (%d of %d outlines in view on edges)",
                          e.regions_on_edges, e.regions);
      // The refinement may leave the basin it was accepted in (a strong
      // perspective pulled toward other edges): judge the transform given.
      if (!refined_passes)
        return cv::format("best consistent set's refined outlines are not on photo edges (contrast %.2f < %.2f)",
                          e.contrast, evidence->options().min_contrast);
      // The photo's lean (edge_evidence.h), last: the checks judge the
      // answer without it (two more parameters would also help a wrong
      // set's outlines onto edges); it only moves an accepted answer from
      // the mean roof to the ground. From where the lean-free refinement
      // started: its result has put the mean roof on the edges, a basin
      // the lean rarely leaves.
      cv::Point2d lean;
      cv::Matx33d T3 = dp.size() >= 3 ? evidence->RefineOutward(start_T, cv::boundingRect(dp), persp, &lean)
                                      : evidence->Refine(start_T, persp, true, nullptr, &lean);
      // A second start: the region pairs refitted with the lean (see
      // JointLeanFit). It replaces the first only when its refinement ends
      // with a clearly higher edge contrast (joint_lean_gain): right fixes
      // gained 24-51 %, while answers it moved off the truth gained 2-9 %.
      cv::Matx33d Tj;
      cv::Point2d lj;
      if (opt.joint_lean_fit && dp.size() >= 3 &&
          JointLeanFit(depth, pairs, verifier, start_T, 2 * tol, *evidence, &Tj, &lj)) {
        const cv::Matx33d T3j = evidence->RefineOutward(Tj, cv::boundingRect(dp), persp, &lj);
        const double c0 = evidence->Evaluate(T3, lean).contrast, c1 = evidence->Evaluate(T3j, lj).contrast;
        if (c1 >= (1 + opt.joint_lean_gain) * c0) T3 = T3j, lean = lj;
      }
      lean_answer = LeanAnswer{T3, lean};
    }
    // A nadir photo: the projective divisor changes little across it, and
    // its pixels are square.
    if (const std::string shape = NadirShape(f.T, photo_extent, opt); !shape.empty())
      return "best consistent set " + shape;
    double scale, rot;
    if (!LocalScaleRotation(f.T, photo[pairs[0].first].centroid, &scale, &rot))
      return "refined transform is degenerate or reflecting";
    // The lean answer replaces the accepted one if it passes the same
    // checks. (Not "if it stays near it": the lean-free answer, fitted to
    // the roofs, errs most far from them, where the two differ most.)
    EdgeScore e3;
    if (lean_answer && LeanAnswerPasses(*evidence, lean_answer->T, lean_answer->lean, res.edge, opt, photo_extent,
                                        photo[pairs[0].first].centroid, &e3) &&
        LeanKeepsRoofs(*evidence, f.T, res.edge, lean_answer->T, lean_answer->lean, opt.lean_min_roof_ratio, &e3)) {
      f.T = lean_answer->T, res.edge = e3, res.lean_px_per_m = lean_answer->lean;
      verifier.ClosestPoints(f.T, pairs, 2 * tol, &f.rms);
    }
    if (image_ok) {
      const std::string veto = RoofVeto(*evidence, f.T, res.lean_px_per_m, &res.edge);
      if (!veto.empty()) {
        res.lean_px_per_m = {};
        return "best consistent set: " + veto;
      }
    }
    if (image_ok && opt.edge_refine && opt.ambiguity_px > 0 && f.m == Model::kPerspective) {
      res.ambiguity_px = AmbiguityGap(*evidence, f.T, res.lean_px_per_m, opt, photo_extent);
      if (res.ambiguity_px > opt.ambiguity_px) {
        res.lean_px_per_m = {};
        return cv::format("best consistent set (%d region pairs) is not determined to %.0f px: an equally good "
                          "pose lies %.1f px away",
                          int(pairs.size()), opt.ambiguity_px, res.ambiguity_px);
      }
    }
    // A wider basin (EdgeEvidence::Relocate) for an accepted answer: a fit
    // right near its region pairs and off elsewhere. It only moves answers
    // every check accepted (seed 119: relocating a candidate the ambiguity
    // check had refused gave it a pose 12.6 px off that passed), and the
    // moved pose must still fit the region pairs as the image route asks
    // (seed 118: one relocation left them at RMS 7.3 px), be a nadir
    // photo's and pass the roofs; else the answer stays where it was.
    if (image_ok && opt.edge_refine) {
      const EdgeEvidence::Relocation rl = evidence->Relocate(f.T, res.lean_px_per_m, f.m == Model::kPerspective);
      double rms = 0;
      if (rl.moved) verifier.ClosestPoints(rl.photo_to_depth, pairs, 2 * tol, &rms);
      EdgeScore e = rl.edge;
      // the RMS bound, unless the edges decide clearly (relocate_rms_free_gain)
      const bool pairs_hold = rms <= opt.edge_rms_factor * max_rms ||
                              (opt.relocate_rms_free_gain > 0 && res.edge.enough &&
                               rl.edge.on >= (1 + opt.relocate_rms_free_gain) * res.edge.on &&
                               rl.edge.contrast >= res.edge.contrast);
      if (rl.moved && pairs_hold && NadirShape(rl.photo_to_depth, photo_extent, opt).empty() &&
          RoofVeto(*evidence, rl.photo_to_depth, rl.lean, &e).empty()) {
        f.T = rl.photo_to_depth, res.edge = e, res.lean_px_per_m = rl.lean, res.relocated_px = rl.moved_px;
        f.rms = rms;
      }
    }
    res.ok = true;
    res.refused.pop_back();
    res.photo_to_depth = f.T;
    res.model = ModelName(f.m);
    res.rms_px = f.rms;
    res.used_principal_directions = cand.from_restricted;
    double rms;
    res.correspondences = verifier.ClosestPoints(f.T, pairs, tol, &rms);
    for (const auto& [p, d] : pairs) {
      RegionMatch m;
      m.a = photo[p].index, m.b = depth[d].index;
      m.cost = full_cost.at<double>(p, d);
      double second = 1.0;
      for (int q = 0; q < P; ++q) if (q != p) second = std::min(second, full_cost.at<double>(q, d));
      m.cost_ratio = m.cost / std::max(second, 1e-9);
      m.shift = MatchDescriptors(photo[p].desc, depth[d].desc).shift;
      res.region_matches.push_back(m);
    }
    res.reason = cv::format("%s, %d region pairs (ratio %.2f), RMS %.2f px, %d hypotheses", res.model.c_str(),
                            int(pairs.size()), ratio, f.rms, res.hypotheses);
    if (res.edge.enough) res.reason += cv::format(", outline edge contrast %.2f", res.edge.contrast);
    return {};
  };

  // 5. search, then try the kept consistent sets best first; continue the
  // search while they fail and hypotheses remain
  std::string why;
  for (;;) {
    const bool more = search();
    for (auto& c : cands) {
      if (c.tried) continue;
      c.tried = true;
      why = finish(c);
      if (why.empty()) {
        res.propagate_ms = timer.ElapsedMs();
        return res;
      }
    }
    if (!more) break;
  }
  // 7. The single-pair route (issue 21): when no consistent set of region
  // pairs passes (a photo segmentation that finds few roofs leaves one or
  // two right pairs), each pair's own transform is judged by the image
  // check alone: every depth outline in view must lie on photo edges.
  if (why.empty())
    why = cv::format("best hypothesis explains %d region pair(s) (need %d), ratio %.2f (need %.2f)", best_count,
                     min_regions, best_ratio, min_inlier_ratio);
  if (single_pair_possible) {
    const std::string single =
        SinglePairRoute(photo, depth, ddesc, ddesc_region, hyps, verifier, opt, *evidence, photo_extent, &res);
    if (single.empty()) {
      res.propagate_ms = timer.ElapsedMs();
      return res;
    }
    why += "; " + single;
  }
  res.reason = "no registration found: " + why;
  res.propagate_ms = timer.ElapsedMs();
  return res;
}

}  // namespace mvkp
