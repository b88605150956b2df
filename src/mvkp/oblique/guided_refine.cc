#include "mvkp/oblique/guided_refine.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

namespace {

constexpr int kMaxRadius = 12;  // template half-size, view px (4 at least)

// Sub-pixel offset of a peak from three samples (parabola), in [-0.5, 0.5].
double Parabola(double a, double b, double c) {
  const double d = a - 2 * b + c;
  if (!(std::abs(d) > 1e-12)) return 0;
  return std::clamp(0.5 * (a - c) / d, -0.5, 0.5);
}

cv::Point2d Apply(const cv::Matx33d& H, cv::Point2d p) {
  const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1);
  return {v[0] / v[2], v[1] / v[2]};
}

// view px per nadir px at p (the map's local area scale, square-rooted)
double LocalScale(const cv::Matx33d& H, cv::Point2d p) {
  const cv::Point2d a = Apply(H, p), bx = Apply(H, p + cv::Point2d(1, 0)), by = Apply(H, p + cv::Point2d(0, 1));
  const cv::Point2d u = bx - a, v = by - a;
  return std::sqrt(std::abs(u.x * v.y - u.y * v.x));
}

double Residual(const cv::Matx34d& P, const cv::Point3d& X, const cv::Point2d& x) {
  const cv::Vec3d v = P * cv::Vec4d(X.x, X.y, X.z, 1);
  if (!(v[2] > 0)) return 1e9;
  return std::hypot(v[0] / v[2] - x.x, v[1] / v[2] - x.y);
}

}  // namespace

void GuidedRefineOptions::Check() const {
  Require(max_corners >= 1 && max_corners <= 100000 && corner_spacing_px >= 1 && flat_radius_px >= 1 &&
              flat_radius_px <= 32 && max_height_step_m >= 0 && max_tries >= 1 && search_px >= 1 && search_px <= 64 &&
              min_ncc > 0 && min_ncc < 1 && min_contrast >= 0 && inlier_px > 0 && min_pairs >= 6 && keep_first >= 0 &&
              keep_first <= 1 && keep_first_px > 0,
          ErrorCode::kInvalidArgument,
          "GuidedRefineOptions: max_corners in [1, 100000], corner_spacing_px >= 1, flat_radius_px in [1, 32], "
          "max_height_step_m >= 0, max_tries >= 1, search_px in [1, 64], min_ncc in (0, 1), min_contrast >= 0, "
          "inlier_px > 0, min_pairs >= 6, keep_first in [0, 1], keep_first_px > 0");
}

GuidedRefiner::GuidedRefiner(const cv::Mat& nadir_gray, const NadirLifter& lifter, const GuidedRefineOptions& o)
    : options_(o) {
  o.Check();
  Require(!nadir_gray.empty() && nadir_gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "GuidedRefiner: an 8-bit grey nadir photo is required");
  nadir_ = nadir_gray.clone();  // kept: the caller's buffer may not outlive us (numpy)
  cv::pyrDown(nadir_, half_);
  std::vector<cv::Point2f> pts;
  cv::goodFeaturesToTrack(nadir_, pts, o.max_corners, 0.01, o.corner_spacing_px, cv::noArray(), 5);
  for (const auto& p : pts) {
    Corner c{p, {}, 0, 0};
    if (!lifter.Lift(cv::Point2d(p), &c.world, &c.above_m)) continue;
    // how far around it (nadir px) the DSM stays within max_height_step_m
    const double cells_per_px = LocalScale(lifter.PlaneToDepth(c.above_m), cv::Point2d(p));
    for (double rad : {1.0, 2.0, 3.0, 5.0, 8.0}) {
      if (rad > o.flat_radius_px) break;
      const double step = lifter.HeightStep(cv::Point2d(p), rad * cells_per_px);
      if (step < 0 || step > o.max_height_step_m) break;
      c.flat_px = rad;
    }
    if (c.flat_px <= 0) continue;
    corners_.push_back(c);
  }
}

GuidedRefinement GuidedRefiner::Refine(const cv::Mat& view, const cv::Matx33d& K, const NadirLifter& lifter,
                                       const std::vector<cv::Point3d>& world, const std::vector<cv::Point2d>& pixels,
                                       ViewPose* pose) const {
  Require(pose != nullptr && !view.empty() && view.type() == CV_8UC1 && world.size() == pixels.size(),
          ErrorCode::kInvalidArgument, "GuidedRefiner::Refine: a pose, an 8-bit grey view and matching pairs");
  GuidedRefinement g;
  if (!pose->ok) return g;
  const GuidedRefineOptions& o = options_;
  const cv::Matx34d P0 = pose->camera;
  const double res = lifter.res_m();
  const int w = o.search_px;
  // corners predicted inside the view, with room for the largest template
  std::vector<std::size_t> in;
  for (std::size_t i = 0; i < corners_.size(); ++i) {
    const cv::Vec3d v = P0 * cv::Vec4d(corners_[i].world.x, corners_[i].world.y, corners_[i].world.z, 1);
    if (!(v[2] > 0)) continue;
    const double x = v[0] / v[2], y = v[1] / v[2];
    const int m = kMaxRadius + w + 2;
    if (x >= m && y >= m && x < view.cols - m && y < view.rows - m) in.push_back(i);
  }
  const double every = std::max(1.0, double(in.size()) / o.max_tries);
  std::vector<cv::Point3d> X;
  std::vector<cv::Point2d> x;
  cv::Mat T, win, R;
  for (double k = 0; k < double(in.size()); k += every) {
    const Corner& c = corners_[in[std::size_t(k)]];
    if (!lifter.Visible(c.world, pose->centre_m)) continue;
    const cv::Matx33d H = GroundHomography(P0, res, c.world.z) * lifter.PlaneToDepth(c.above_m);
    const cv::Point2d pred = Apply(H, cv::Point2d(c.nadir));
    const double s = LocalScale(H, cv::Point2d(c.nadir));
    if (!std::isfinite(pred.x) || !std::isfinite(pred.y) || !(s > 0.1 && s < 10)) continue;
    // the template (view px) stays on the corner's flat surroundings, or
    // at least its middle 5 x 5 px does (a view coarser than the photo)
    if (c.flat_px * s < 2) continue;
    const int r = std::clamp(int(c.flat_px * s), 4, kMaxRadius);
    const int x0 = int(std::lround(pred.x)), y0 = int(std::lround(pred.y));
    const cv::Rect wr(x0 - r - w, y0 - r - w, 2 * (r + w) + 1, 2 * (r + w) + 1);
    if ((wr & cv::Rect(0, 0, view.cols, view.rows)) != wr) continue;
    // the template: the nadir photo seen from the view, around the prediction
    const bool coarse = s < 0.6;  // the view is coarser: warp from the half-size level
    const cv::Mat& src = coarse ? half_ : nadir_;
    const cv::Matx33d Hs = coarse ? H * cv::Matx33d(2, 0, 0, 0, 2, 0, 0, 0, 1) : H;
    const cv::Matx33d M = Hs.inv() * cv::Matx33d(1, 0, x0 - r, 0, 1, y0 - r, 0, 0, 1);
    bool inside = true;
    for (const cv::Point2d q : {cv::Point2d(0, 0), cv::Point2d(2 * r, 0), cv::Point2d(0, 2 * r), cv::Point2d(2 * r, 2 * r)}) {
      const cv::Point2d u = Apply(M, q);
      inside = inside && u.x >= 0 && u.y >= 0 && u.x <= src.cols - 1 && u.y <= src.rows - 1;
    }
    if (!inside) continue;
    cv::warpPerspective(src, T, cv::Mat(M), cv::Size(2 * r + 1, 2 * r + 1), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
    cv::Scalar mean, sd;
    cv::meanStdDev(T, mean, sd);
    if (sd[0] < o.min_contrast) continue;
    ++g.tried;
    win = view(wr).clone();
    const double sv = coarse ? s * 2 : s;  // view px per source px
    if (sv > 1.3) cv::GaussianBlur(win, win, cv::Size(), 0.5 * std::sqrt(sv * sv - 1));
    cv::matchTemplate(win, T, R, cv::TM_CCOEFF_NORMED);
    double best = 0;
    cv::Point at;
    cv::minMaxLoc(R, nullptr, &best, nullptr, &at);
    if (best < o.min_ncc || at.x == 0 || at.y == 0 || at.x == R.cols - 1 || at.y == R.rows - 1) continue;
    const double dx = Parabola(R.at<float>(at.y, at.x - 1), R.at<float>(at.y, at.x), R.at<float>(at.y, at.x + 1));
    const double dy = Parabola(R.at<float>(at.y - 1, at.x), R.at<float>(at.y, at.x), R.at<float>(at.y + 1, at.x));
    ++g.found;
    X.push_back(c.world);
    x.emplace_back(x0 - w + at.x + dx, y0 - w + at.y + dy);
  }
  if (g.found < o.min_pairs) return g;
  // refit from the first camera, tightening the residual kept
  cv::Point3d c0(0, 0, 0);
  for (const auto& p : X) c0 += p;
  c0 *= 1.0 / double(X.size());
  cv::Mat rvec, tvec;
  cv::Rodrigues(cv::Mat(pose->R), rvec);
  const cv::Vec3d tc = pose->t + pose->R * cv::Vec3d(c0.x, c0.y, c0.z);  // x_cam = R (X - c0) + tc
  tvec = (cv::Mat_<double>(3, 1) << tc[0], tc[1], tc[2]);
  // least squares from the first camera, the residual kept tightened each
  // round (a few pairs correlate on the wrong spot; a minimal-set RANSAC on
  // these near-planar points also finds the mirror camera behind them)
  cv::Matx34d P = P0;
  cv::Matx33d Rm = pose->R;
  cv::Vec3d t = pose->t;
  for (double thr : {double(w) + 1, 0.5 * w, 3.0, o.inlier_px, o.inlier_px}) {
    std::vector<cv::Point3d> Xi;
    std::vector<cv::Point2d> xi;
    for (std::size_t i = 0; i < X.size(); ++i)
      if (Residual(P, X[i], x[i]) <= std::max(thr, o.inlier_px)) Xi.push_back(X[i] - c0), xi.push_back(x[i]);
    if (int(Xi.size()) < o.min_pairs) return g;
    cv::solvePnPRefineLM(Xi, xi, cv::Mat(K), cv::noArray(), rvec, tvec);
    cv::Rodrigues(rvec, Rm);
    const cv::Vec3d tcn(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    t = tcn - Rm * cv::Vec3d(c0.x, c0.y, c0.z);
    P = CameraMatrix(K, Rm, t);
  }
  double ss = 0, shift = 0;
  int n = 0;
  for (std::size_t i = 0; i < X.size(); ++i) {
    const double e = Residual(P, X[i], x[i]);
    if (e > o.inlier_px) continue;
    ss += e * e, ++n;
    const cv::Vec3d a = P * cv::Vec4d(X[i].x, X[i].y, X[i].z, 1), b = P0 * cv::Vec4d(X[i].x, X[i].y, X[i].z, 1);
    shift += std::hypot(a[0] / a[2] - b[0] / b[2], a[1] / a[2] - b[1] / b[2]);
  }
  if (n < o.min_pairs) return g;
  // the first camera's inliers must still agree
  int first = 0, kept = 0;
  for (std::size_t i = 0; i < world.size(); ++i) {
    if (i >= pose->inlier.size() || !pose->inlier[i]) continue;
    ++first;
    kept += Residual(P, world[i], pixels[i]) <= o.keep_first_px;
  }
  if (first > 0 && kept < o.keep_first * first) return g;
  g.refined = true;
  g.inliers = n;
  g.rms_px = std::sqrt(ss / n);
  g.shift_px = shift / n;
  pose->camera = P;
  pose->R = Rm;
  pose->t = t;
  pose->centre_m = -(Rm.t() * t);
  return g;
}

}  // namespace mvkp
