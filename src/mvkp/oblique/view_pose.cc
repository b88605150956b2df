#include "mvkp/oblique/view_pose.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

void ViewPoseOptions::Check() const {
  Require(ransac_px > 0 && iterations >= 100 && min_inliers >= 6 && min_inlier_ratio >= 0 && min_inlier_ratio <= 1 &&
              min_inlier_cells >= 0 && min_inlier_cells <= 16,
          ErrorCode::kInvalidArgument,
          "ViewPoseOptions: ransac_px > 0, iterations >= 100, min_inliers >= 6, min_inlier_ratio in [0, 1], "
          "min_inlier_cells in [0, 16]");
}

NadirLifter::NadirLifter(const cv::Mat1f& depth, double res_m, const cv::Matx33d& nadir_to_depth,
                         cv::Point2d lean_px_per_m, double terrain_window_m)
    : res_(res_m), H_(nadir_to_depth), lean_(lean_px_per_m) {
  Require(!depth.empty() && res_m > 0 && std::isfinite(res_m), ErrorCode::kInvalidArgument,
          "NadirLifter: need a depth raster and res_m > 0");
  Require(std::isfinite(lean_.x) && std::isfinite(lean_.y) && cv::norm(lean_) < 10, ErrorCode::kInvalidArgument,
          "NadirLifter: the lean must be finite (depth px per metre)");
  Require(std::abs(cv::determinant(cv::Mat(H_))) > 1e-12, ErrorCode::kInvalidArgument,
          "NadirLifter: the nadir -> depth homography is singular");
  // gaps: the median of the returns (only for lookups; rare)
  std::vector<float> v;
  for (int y = 0; y < depth.rows; y += 4)
    for (int x = 0; x < depth.cols; x += 4)
      if (std::isfinite(depth(y, x))) v.push_back(depth(y, x));
  Require(!v.empty(), ErrorCode::kInvalidArgument, "NadirLifter: the depth raster has no data");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  const float fill = v[v.size() / 2];
  dsm_ = depth.clone();
  cv::Mat1f high = depth.clone();  // gaps high, so that the opening ignores them
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x)
      if (!std::isfinite(depth(y, x))) dsm_(y, x) = fill, high(y, x) = 1e4f;
  const int k = std::max(3, int(std::lround(terrain_window_m / res_m)) | 1);
  cv::Mat1f terrain;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k));
  cv::morphologyEx(high, terrain, cv::MORPH_OPEN, kernel);
  for (float& t : terrain) if (t > 5e3f) t = fill;
  cv::GaussianBlur(terrain, terrain, cv::Size(), std::max(1.0, k / 6.0));
  above_ = dsm_ - terrain;
  for (float& a : above_) a = std::max(0.f, a);
  double mx = 0;
  cv::minMaxLoc(above_, nullptr, &mx);
  max_above_ = float(std::min(mx, 300.0));
  double lo = 0, hi = 0;
  cv::minMaxLoc(dsm_, &lo, &hi);
  dsm_max_ = float(hi);
  std::vector<float> g(terrain.begin(), terrain.end());
  std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
  ground_z_ = g[g.size() / 2];
}

bool NadirLifter::Locate(cv::Point2d p, cv::Point2d* out, double* above_m) const {
  const cv::Vec3d h = H_ * cv::Vec3d(p.x, p.y, 1);
  if (!(std::abs(h[2]) > 1e-12)) return false;
  const cv::Point2d q0(h[0] / h[2], h[1] / h[2]);
  const int w = dsm_.cols, hh = dsm_.rows;
  if (!std::isfinite(q0.x) || !std::isfinite(q0.y) || std::abs(q0.x) > 1e7 || std::abs(q0.y) > 1e7) return false;
  auto cell = [&](cv::Point2d q) {
    return cv::Point(std::clamp(int(std::lround(q.x)), 0, w - 1), std::clamp(int(std::lround(q.y)), 0, hh - 1));
  };
  double t = 0;
  if (cv::norm(lean_) > 1e-9) {
    // down the lean from the highest point: the first surface at least t up
    for (double s = max_above_; s > 0; s -= 0.25) {
      const cv::Point c = cell(q0 - lean_ * s);
      if (above_(c) >= s) {
        t = s;
        break;
      }
    }
  }
  const cv::Point2d q = q0 - lean_ * t;
  if (q.x < 0 || q.y < 0 || q.x > w - 1 || q.y > hh - 1) return false;
  *out = q;
  if (above_m) *above_m = t;
  return true;
}

bool NadirLifter::Lift(cv::Point2d p, cv::Point3d* world) const { return Lift(p, world, nullptr); }

cv::Matx33d NadirLifter::PlaneToDepth(double above_m) const {
  const cv::Matx33d T(1, 0, -lean_.x * above_m, 0, 1, -lean_.y * above_m, 0, 0, 1);
  return T * H_;
}

bool NadirLifter::Visible(const cv::Point3d& X, const cv::Vec3d& c, double clearance_m) const {
  const cv::Vec3d d(c[0] - X.x, c[1] - X.y, c[2] - X.z);
  const double horiz = std::hypot(d[0], d[1]);
  if (!(d[2] > 0) || !std::isfinite(horiz)) return false;
  if (horiz < 1e-9) return true;
  const double step = 0.5 * res_;
  // from just off the point (its own surface) until the ray is above every roof
  for (double s = 2 * res_; s < horiz; s += step) {
    const double z = X.z + d[2] * (s / horiz);
    if (z > dsm_max_) break;
    const double cx = (X.x + d[0] * (s / horiz)) / res_, cy = -(X.y + d[1] * (s / horiz)) / res_;
    const int ix = int(std::lround(cx)), iy = int(std::lround(cy));
    if (ix < 0 || iy < 0 || ix >= dsm_.cols || iy >= dsm_.rows) break;
    if (dsm_(iy, ix) > z + clearance_m) return false;
  }
  return true;
}

bool NadirLifter::Lift(cv::Point2d p, cv::Point3d* world, double* above_m) const {
  cv::Point2d q;
  if (!Locate(p, &q, above_m)) return false;
  const cv::Point c(std::clamp(int(std::lround(q.x)), 0, dsm_.cols - 1),
                    std::clamp(int(std::lround(q.y)), 0, dsm_.rows - 1));
  *world = cv::Point3d(q.x * res_, -q.y * res_, dsm_(c));
  return true;
}

double NadirLifter::HeightStep(cv::Point2d p, double radius_cells) const {
  cv::Point2d q;
  if (!Locate(p, &q)) return -1;
  const int r = std::clamp(int(std::ceil(radius_cells)), 0, 64);
  const int cx = std::clamp(int(std::lround(q.x)), 0, dsm_.cols - 1);
  const int cy = std::clamp(int(std::lround(q.y)), 0, dsm_.rows - 1);
  const double r2 = std::max(radius_cells, 0.0) * std::max(radius_cells, 0.0) + 1e-9;
  float lo = dsm_(cy, cx), hi = lo;
  for (int y = std::max(0, cy - r); y <= std::min(dsm_.rows - 1, cy + r); ++y)
    for (int x = std::max(0, cx - r); x <= std::min(dsm_.cols - 1, cx + r); ++x) {
      if (double(x - cx) * (x - cx) + double(y - cy) * (y - cy) > r2) continue;
      lo = std::min(lo, dsm_(y, x));
      hi = std::max(hi, dsm_(y, x));
    }
  return double(hi - lo);
}

ViewPose EstimateViewPose(const std::vector<cv::Point3d>& world, const std::vector<cv::Point2d>& pixels,
                          const cv::Matx33d& K, const ViewPoseOptions& o, cv::Size image) {
  o.Check();
  Require(world.size() == pixels.size(), ErrorCode::kInvalidArgument,
          "EstimateViewPose: world and pixels must have the same size");
  ViewPose r;
  r.matches = int(world.size());
  r.inlier.assign(world.size(), 0);
  if (r.matches < o.min_inliers) {
    r.reason = cv::format("%d matches lift into the depth raster (need %d)", r.matches, o.min_inliers);
    return r;
  }
  // centre the world points: PnP on coordinates of hundreds of metres loses digits
  cv::Point3d c0(0, 0, 0);
  for (const auto& X : world) c0 += X;
  c0 *= 1.0 / double(world.size());
  std::vector<cv::Point3d> Xc;
  for (const auto& X : world) Xc.push_back(X - c0);
  cv::Mat rvec, tvec;
  std::vector<int> inl;
  cv::setRNGSeed(1);  // deterministic RANSAC
  const bool found = cv::solvePnPRansac(Xc, pixels, cv::Mat(K), cv::noArray(), rvec, tvec, false, o.iterations,
                                        float(o.ransac_px), 0.9999, inl, cv::SOLVEPNP_AP3P);
  if (!found || int(inl.size()) < o.min_inliers) {
    r.reason = cv::format("no camera: %d of %d pairs agree (need %d)", int(inl.size()), r.matches, o.min_inliers);
    return r;
  }
  std::vector<cv::Point3d> Xi;
  std::vector<cv::Point2d> pi;
  for (int i : inl) Xi.push_back(Xc[size_t(i)]), pi.push_back(pixels[size_t(i)]);
  cv::solvePnPRefineLM(Xi, pi, cv::Mat(K), cv::noArray(), rvec, tvec);
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  const cv::Vec3d tc(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  // back to the world frame: x_cam = R (X - c0) + tc = R X + (tc - R c0)
  const cv::Vec3d t = tc - R * cv::Vec3d(c0.x, c0.y, c0.z);
  r.camera = CameraMatrix(K, R, t);
  r.R = R, r.t = t;
  r.centre_m = -(R.t() * t);
  double ss = 0;
  int n = 0;
  for (size_t i = 0; i < world.size(); ++i) {
    const cv::Vec3d X(world[i].x, world[i].y, world[i].z);
    const cv::Vec3d xc = R * X + t;
    const cv::Vec3d p = K * xc;
    if (!(xc[2] > 0)) continue;
    const double e = std::hypot(p[0] / p[2] - pixels[i].x, p[1] / p[2] - pixels[i].y);
    if (e <= o.ransac_px) r.inlier[i] = 1, ss += e * e, ++n;
  }
  r.inliers = n;
  r.rms_px = n ? std::sqrt(ss / n) : 0;
  const std::string what = cv::format("%d of %d pairs agree, reprojection RMS %.2f px", n, r.matches, r.rms_px);
  if (n < o.min_inliers || n < o.min_inlier_ratio * r.matches) {
    r.reason = "no camera: " + what + cv::format(" (need %d and %.0f %%)", o.min_inliers, 100 * o.min_inlier_ratio);
    return r;
  }
  if (!image.empty()) {
    std::vector<char> cell(16, 0);
    for (size_t i = 0; i < pixels.size(); ++i)
      if (r.inlier[i])
        cell[size_t(std::clamp(int(4 * pixels[i].y / image.height), 0, 3) * 4 +
                    std::clamp(int(4 * pixels[i].x / image.width), 0, 3))] = 1;
    const int cells = int(std::count(cell.begin(), cell.end(), 1));
    if (cells < o.min_inlier_cells) {
      r.reason = "no camera: " + what + cv::format(", but only in %d of the view's 4 x 4 cells (need %d)", cells,
                                                   o.min_inlier_cells);
      return r;
    }
  }
  if (!(r.centre_m[2] > c0.z)) {  // (inliers are in front of it by construction)
    r.reason = "no camera: " + what + ", but the camera is not above the scene";
    return r;
  }
  r.ok = true;
  r.reason = what;
  return r;
}

cv::Matx34d CameraMatrix(const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t) {
  cv::Matx34d Rt;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) Rt(i, j) = R(i, j);
    Rt(i, 3) = t[i];
  }
  return K * Rt;
}

cv::Matx33d GroundHomography(const cv::Matx34d& P, double res_m, double z) {
  // depth px (c, r) -> world (c res, -r res, z)
  cv::Matx33d H;
  for (int i = 0; i < 3; ++i) {
    H(i, 0) = P(i, 0) * res_m;
    H(i, 1) = -P(i, 1) * res_m;
    H(i, 2) = P(i, 2) * z + P(i, 3);
  }
  return H;
}

}  // namespace mvkp
