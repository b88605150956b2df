#include "mvkp/oblique/register_view.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void ViewRegistrarOptions::Check() const {
  tiles.Check();
  pose.Check();
  guided.Check();
  outline.Check();
  Require(!scales.empty(), ErrorCode::kInvalidArgument, "ViewRegistrarOptions: at least one scale");
  for (double s : scales)
    Require(s >= 0.05 && s <= 4, ErrorCode::kInvalidArgument, "ViewRegistrarOptions: scales must be in [0.05, 4]");
  Require(nadir_gsd_m >= 0 && nadir_gsd_m <= 100, ErrorCode::kInvalidArgument,
          "ViewRegistrarOptions: nadir_gsd_m must be in [0, 100]");
  Require(max_height_step_m >= 0 && max_height_step_m <= 1000 && step_radius_px >= 0 && step_radius_px <= 20,
          ErrorCode::kInvalidArgument,
          "ViewRegistrarOptions: max_height_step_m must be in [0, 1000], step_radius_px in [0, 20]");
}

double NadirGsd(cv::Size size, const cv::Matx33d& H, double res_m) {
  const double x = (size.width - 1) / 2.0, y = (size.height - 1) / 2.0;
  const double w = H(2, 0) * x + H(2, 1) * y + H(2, 2);
  if (!(std::abs(w) > 1e-12)) return 0;
  const double u = (H(0, 0) * x + H(0, 1) * y + H(0, 2)) / w, v = (H(1, 0) * x + H(1, 1) * y + H(1, 2)) / w;
  // Jacobian of the projective map at (x, y)
  const double a = (H(0, 0) - u * H(2, 0)) / w, b = (H(0, 1) - u * H(2, 1)) / w;
  const double c = (H(1, 0) - v * H(2, 0)) / w, e = (H(1, 1) - v * H(2, 1)) / w;
  return res_m * std::sqrt(std::abs(a * e - b * c));
}

cv::Matx33d ViewIntrinsics(cv::Size size, double hfov_deg, double focal_px) {
  Require(size.width > 0 && size.height > 0, ErrorCode::kInvalidArgument, "ViewIntrinsics: empty view");
  Require(focal_px > 0 || (hfov_deg > 0 && hfov_deg < 180), ErrorCode::kInvalidArgument,
          "ViewIntrinsics: hfov must be in (0, 180) degrees, or the focal length > 0");
  const double f = focal_px > 0 ? focal_px : (size.width / 2.0) / std::tan(hfov_deg * CV_PI / 360);
  return {f, 0, (size.width - 1) / 2.0, 0, f, (size.height - 1) / 2.0, 0, 0, 1};
}

namespace {

NadirTilesOptions TileOptions(const ViewRegistrarOptions& o, double gsd) {
  o.Check();
  NadirTilesOptions t = o.tiles;
  if (o.nadir_gsd_m > 0 && gsd > 0 && gsd < o.nadir_gsd_m) t.photo_scale = std::max(0.05, gsd / o.nadir_gsd_m);
  return t;
}

}  // namespace

ViewRegistrar::ViewRegistrar(const cv::Mat1f& depth, double res_m, const cv::Mat& nadir,
                             const cv::Matx33d& nadir_to_depth, cv::Point2d lean, const ViewRegistrarOptions& options)
    : options_(options),
      depth_(depth.clone()),
      nadir_(nadir.clone()),
      res_m_(res_m),
      nadir_to_depth_(nadir_to_depth),
      nadir_gsd_m_(NadirGsd(nadir.size(), nadir_to_depth, res_m)),
      tiles_(nadir, TileOptions(options, nadir_gsd_m_)),
      lifter_(depth, res_m, nadir_to_depth, lean),
      refiner_(nadir, lifter_, options.guided),
      outline_(depth, res_m, options.outline) {}

void ViewRegistrar::Restage(const cv::Matx33d& nadir_to_depth, cv::Point2d lean) {
  NadirLifter lifter(depth_, res_m_, nadir_to_depth, lean);  // checks the arguments first
  GuidedRefiner refiner(nadir_, lifter, options_.guided);
  lifter_ = std::move(lifter);
  refiner_ = std::move(refiner);
  nadir_to_depth_ = nadir_to_depth;
}

bool Stage1Correction(const std::vector<ViewRegistration>& views, double res_m, cv::Matx33d* C, int* inliers,
                      const Stage1CorrectionOptions& o) {
  Require(res_m > 0 && C != nullptr, ErrorCode::kInvalidArgument, "Stage1Correction: res_m > 0 and C required");
  Require(o.ransac_px > 0 && o.min_inliers >= 3 && o.min_views >= 1, ErrorCode::kInvalidArgument,
          "Stage1CorrectionOptions: ransac_px > 0, min_inliers >= 3, min_views >= 1");
  std::vector<cv::Point2f> from, to;
  std::vector<int> view_of;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const ViewRegistration& r = views[v];
    if (!r.pose.ok || !r.outline.replaced || r.pose.inlier.size() != r.matches.size()) continue;
    for (std::size_t k = 0; k < r.matches.size(); ++k) {
      if (!r.pose.inlier[k]) continue;
      const cv::Point3d& w = r.world[k];
      // the replaced camera's view of the plane z = w.z, from depth px
      const cv::Matx33d G = GroundHomography(r.pose.camera, res_m, w.z);
      if (!(std::abs(cv::determinant(G)) > 1e-12)) continue;
      const cv::Vec3d q = G.inv() * cv::Vec3d(r.matches[k].view.x, r.matches[k].view.y, 1);
      if (!(std::abs(q[2]) > 1e-12)) continue;
      const double qx = q[0] / q[2], qy = q[1] / q[2];
      if (!(std::abs(qx) < 1e7 && std::abs(qy) < 1e7)) continue;  // also NaN
      const cv::Point2f dst{float(qx), float(qy)};
      from.emplace_back(float(w.x / res_m), float(-w.y / res_m));
      to.push_back(dst);
      view_of.push_back(int(v));
    }
  }
  if (inliers) *inliers = 0;
  if (int(from.size()) < o.min_inliers) return false;
  std::vector<uchar> mask;
  // a similarity: an affine or a homography fitted to the views' pairs did
  // no better (held-out seed 113 and seeds 1, 3, 4, 112 with stage 1 =
  // mvkp register: the same right and wrong counts, median 0.67-0.88 px)
  const cv::Mat A = cv::estimateAffinePartial2D(from, to, mask, cv::RANSAC, o.ransac_px, 5000, 0.999, 20);
  if (A.empty()) return false;
  int n = 0;
  std::vector<int> vs;
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i]) ++n, vs.push_back(view_of[i]);
  std::sort(vs.begin(), vs.end());
  const int nviews = int(std::unique(vs.begin(), vs.end()) - vs.begin());
  if (inliers) *inliers = n;
  if (n < o.min_inliers || nviews < o.min_views) return false;
  *C = cv::Matx33d(A.at<double>(0, 0), A.at<double>(0, 1), A.at<double>(0, 2), A.at<double>(1, 0),
                   A.at<double>(1, 1), A.at<double>(1, 2), 0, 0, 1);
  return true;
}

ViewRegistration ViewRegistrar::Register(const cv::Mat& view, const cv::Matx33d& K) const {
  Require(!view.empty() && view.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "ViewRegistrar: an 8-bit grey view is required");
  ViewRegistration r;
  Timer tm;
  for (double sc : options_.scales) {
    tm.Restart();
    std::vector<NadirMatch> found = tiles_.Match(view, sc);
    r.match_ms += tm.ElapsedMs();
    tm.Restart();
    std::vector<NadirMatch> kept;
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2d> x;
    // in the tiles' pixels (the photo resized to nadir_gsd_m when finer)
    const double step_cells =
        options_.step_radius_px * std::max(nadir_gsd_m_, options_.nadir_gsd_m) / lifter_.res_m();
    for (const auto& c : found) {
      cv::Point3d w;
      if (options_.max_height_step_m > 0 &&
          !(lifter_.HeightStep(cv::Point2d(c.nadir), step_cells) <= options_.max_height_step_m))
        continue;
      if (lifter_.Lift(cv::Point2d(c.nadir), &w)) X.push_back(w), x.emplace_back(c.view), kept.push_back(c);
    }
    ViewPose p = EstimateViewPose(X, x, K, options_.pose, view.size());
    r.pose_ms += tm.ElapsedMs();
    if (r.scale == 0 || p.ok || (!r.pose.ok && p.inliers > r.pose.inliers))
      r.matches = std::move(kept), r.world = std::move(X), r.pose = std::move(p), r.scale = sc;
    if (r.pose.ok) break;
  }
  if (r.pose.ok && options_.refine) {
    tm.Restart();
    std::vector<cv::Point2d> px;
    for (const auto& m : r.matches) px.emplace_back(m.view);
    r.refinement = refiner_.Refine(view, K, lifter_, r.world, px, &r.pose);
    r.refine_ms = tm.ElapsedMs();
  }
  if (r.pose.ok && options_.outline_refine) {
    tm.Restart();
    r.outline = outline_.Refine(view, K, lifter_, &r.pose);
    r.outline_ms = tm.ElapsedMs();
  }
  if (r.pose.ok) {
    std::vector<int> tiles, cells;
    float zlo = 1e30f, zhi = -1e30f;
    for (std::size_t k = 0; k < r.matches.size(); ++k) {
      if (!r.pose.inlier[k]) continue;
      tiles.push_back(r.matches[k].tile);
      cells.push_back(std::clamp(int(4 * r.matches[k].view.y / view.rows), 0, 3) * 4 +
                      std::clamp(int(4 * r.matches[k].view.x / view.cols), 0, 3));
      zlo = std::min(zlo, float(r.world[k].z)), zhi = std::max(zhi, float(r.world[k].z));
    }
    std::sort(tiles.begin(), tiles.end());
    std::sort(cells.begin(), cells.end());
    r.inlier_tiles = int(std::unique(tiles.begin(), tiles.end()) - tiles.begin());
    r.inlier_cells = int(std::unique(cells.begin(), cells.end()) - cells.begin());
    r.inlier_height_span_m = zhi >= zlo ? double(zhi - zlo) : 0.0;
  }
  return r;
}

}  // namespace mvkp
