#include "mvkp/oblique/register_view.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

const char* ViewMethodName(ViewMethod m) {
  switch (m) {
    case ViewMethod::kMvkp: return "mvkp";
    case ViewMethod::kFusion: return "fusion";
    case ViewMethod::kAuto: return "auto";
  }
  return "?";
}

void ViewRegistrarOptions::Check() const {
  tiles.Check();
  fusion.Check();
  rectify.Check();
  for (double t : fusion_tilts)
    Require(t >= 0 && t < 89, ErrorCode::kInvalidArgument, "ViewRegistrarOptions: fusion_tilts must be in [0, 89)");
  Require(max_view_px == 0 || (max_view_px >= 64 && max_view_px <= 65536), ErrorCode::kInvalidArgument,
          "ViewRegistrarOptions: max_view_px must be 0 or in [64, 65536]");
  Require(fusion_min_confirmed >= 6 && fusion_min_confirmed_share >= 0 && fusion_min_confirmed_share <= 1 &&
              fusion_lift_m >= 0 && fusion_lift_m <= 20 && fusion_hypotheses >= 0 &&
              fusion_hypotheses <= 1000 && fusion_min_features >= 1 && !fusion_radii.empty(),
          ErrorCode::kInvalidArgument,
          "ViewRegistrarOptions: fusion_min_confirmed >= 6, fusion_min_confirmed_share in [0, 1], fusion_lift_m in [0, 20], fusion_hypotheses in "
          "[0, 1000], fusion_min_features >= 1, fusion_radii not empty");
  for (double r : fusion_radii)
    Require(r >= 0.5 && r <= 256, ErrorCode::kInvalidArgument, "ViewRegistrarOptions: fusion_radii in [0.5, 256]");
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

cv::Mat Gray(const cv::Mat& image) {
  Require(!image.empty() && image.depth() == CV_8U && (image.channels() == 1 || image.channels() == 3),
          ErrorCode::kInvalidArgument, "ViewRegistrar: an 8-bit grey or BGR image is required");
  if (image.channels() == 1) return image;
  cv::Mat g;
  cv::cvtColor(image, g, cv::COLOR_BGR2GRAY);
  return g;
}

// The colour image for fusion: `color` when given (it must be BGR of the
// same size as `image`), else `image` itself.
const cv::Mat& Colour(const cv::Mat& color, const cv::Mat& image) {
  if (color.empty()) return image;
  Require(color.type() == CV_8UC3 && color.size() == image.size(), ErrorCode::kInvalidArgument,
          "ViewRegistrar: the colour image must be 8-bit BGR of the grey image's size");
  return color;
}

NadirTilesOptions TileOptions(const ViewRegistrarOptions& o, double gsd) {
  o.Check();
  NadirTilesOptions t = o.tiles;
  if (o.nadir_gsd_m > 0 && gsd > 0 && gsd < o.nadir_gsd_m) t.photo_scale = std::max(0.05, gsd / o.nadir_gsd_m);
  return t;
}

}  // namespace

ViewRegistrar::ViewRegistrar(const cv::Mat1f& depth, double res_m, const cv::Mat& nadir,
                             const cv::Matx33d& nadir_to_depth, cv::Point2d lean, const ViewRegistrarOptions& options,
                             const cv::Mat& nadir_color)
    : options_(options),
      depth_(depth.clone()),
      nadir_(Gray(nadir).clone()),
      res_m_(res_m),
      nadir_to_depth_(nadir_to_depth),
      nadir_gsd_m_(NadirGsd(nadir.size(), nadir_to_depth, res_m)),
      lifter_(depth, res_m, nadir_to_depth, lean),
      refiner_(nadir_, lifter_, options.guided),
      outline_(depth, res_m, options.outline) {
  options.Check();
  if (options.method != ViewMethod::kFusion) tiles_.emplace(nadir_, TileOptions(options, nadir_gsd_m_));
  if (options.method != ViewMethod::kMvkp) {
    Timer tm;
    nadir_fusion_ = ExtractFusionFeatures(Colour(nadir_color, nadir), options.fusion);
    fusion_train_ms_ = tm.ElapsedMs();
  }
}

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

void ViewRegistrar::MatchTiles(const cv::Mat& gray, const cv::Matx33d& K, ViewRegistration* out) const {
  ViewRegistration& r = *out;
  Timer tm;
  for (double sc : options_.scales) {
    tm.Restart();
    std::vector<NadirMatch> found = tiles_->Match(gray, sc);
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
    ViewPose p = EstimateViewPose(X, x, K, options_.pose, gray.size());
    r.pose_ms += tm.ElapsedMs();
    if (r.scale == 0 || p.ok || (!r.pose.ok && p.inliers > r.pose.inliers))
      r.matches = std::move(kept), r.world = std::move(X), r.pose = std::move(p), r.scale = sc;
    if (r.pose.ok) break;
  }
}

bool ViewRegistrar::LiftTop(cv::Point2d p, cv::Point3d* world) const {
  const double rad = nadir_gsd_m_ > 0 ? options_.fusion_lift_m / nadir_gsd_m_ : 0;
  bool any = false;
  for (int k = -1; k < 8; ++k) {
    const double a = k * CV_PI / 4;
    const cv::Point2d q = k < 0 ? p : p + cv::Point2d(rad * std::cos(a), rad * std::sin(a));
    cv::Point3d w;
    if (!lifter_.Lift(q, &w)) continue;
    if (!any || w.z > world->z + 1e-9) *world = w;
    any = true;
    if (rad <= 0) break;
  }
  return any;
}

void ViewRegistrar::MatchFeatures(const cv::Mat& view, const cv::Mat& gray, const cv::Matx33d& K,
                                  ViewRegistration* out) const {
  ViewRegistration r;
  r.method = ViewMethod::kFusion;
  r.fusion_ran = true;
  r.scale = 1;
  Timer tm;
  // each tilt hypothesis: the view rectified, its features, their pairs with
  // the nadir photo's lifted to 3-D, and the cameras they propose
  struct Trial {
    double tilt = -1;
    std::vector<cv::Point3d> X;
    std::vector<cv::Point2d> px;
    std::vector<NadirMatch> lifted;
    FusionMatchStats stats;
    int rois = 0, lists = 0;
    std::vector<CameraHypothesis> hyps;
  };
  std::vector<Trial> trials;
  std::vector<double> tilts = options_.fusion_tilts;
  if (tilts.empty()) tilts.push_back(-1);  // the view as it is
  for (double tilt : tilts) {
    Trial t;
    t.tilt = tilt;
    cv::Matx33d back = cv::Matx33d::eye();  // rectified px -> view px
    FusionFeatures vf;
    if (tilt >= 0) {
      const Rectification rc = RectifyForTilt(view.size(), K, tilt, options_.rectify);
      back = rc.H.inv();
      vf = ExtractFusionFeatures(Rectify(view, rc), options_.fusion);
    } else {
      vf = ExtractFusionFeatures(view, options_.fusion);
    }
    t.rois = vf.rois, t.lists = vf.oels;
    std::vector<int> pair_of;
    for (NadirMatch c : MatchFusion(nadir_fusion_, vf, options_.fusion, &t.stats)) {
      const cv::Vec3d q = back * cv::Vec3d(c.view.x, c.view.y, 1);
      if (!(std::abs(q[2]) > 1e-12)) continue;
      const double vx = q[0] / q[2], vy = q[1] / q[2];  // bounded before narrowing
      if (!(vx >= 0 && vy >= 0 && vx <= view.cols - 1 && vy <= view.rows - 1)) continue;
      c.view = cv::Point2f(float(vx), float(vy));
      cv::Point3d w;
      if (LiftTop(cv::Point2d(c.nadir), &w))
        t.X.push_back(w), t.px.emplace_back(c.view), t.lifted.push_back(c), pair_of.push_back(c.tile);
    }
    t.hyps = FeatureHypotheses(t.X, t.px, pair_of, t.stats.view_source, K, options_.fusion_seeds,
                               options_.fusion_consensus);
    trials.push_back(std::move(t));
  }
  // the hypotheses of all tilts, best first: by how well they put the
  // LiDAR's roof outlines on the view's edges (a chance camera puts them
  // on the edge density; a feature pair's own camera is right near it),
  // then by their agreeing features
  const std::shared_ptr<const OutlineEdgeMaps> maps = outline_.EdgeMaps(gray);
  struct Ranked {
    int trial, hyp;
    double score;
  };
  std::vector<Ranked> order;
  for (std::size_t i = 0; i < trials.size(); ++i)
    for (std::size_t k = 0; k < trials[i].hyps.size(); ++k) {
      const CameraHypothesis& h = trials[i].hyps[k];
      if (h.features < options_.fusion_min_features) continue;
      int inside = 0;
      const double sc = outline_.Score(*maps, CameraMatrix(K, h.R, h.t), options_.fusion_score_px, &inside);
      if (inside < options_.fusion_min_outline) continue;
      order.push_back({int(i), int(k), sc});

    }
  auto hyp = [&](const Ranked& q) -> const CameraHypothesis& {
    return trials[std::size_t(q.trial)].hyps[std::size_t(q.hyp)];
  };
  std::stable_sort(order.begin(), order.end(), [&](const Ranked& a, const Ranked& b) {
    return a.score > b.score || (a.score == b.score && hyp(a).features > hyp(b).features);
  });
  r.match_ms = tm.ElapsedMs();
  tm.Restart();
  // Each, in turn, fitted to the LiDAR's outlines seen as edges of the view
  // (the global context), then confirmed by the nadir photo's texture; the
  // first confirmed camera answers.
  int tried = 0, best_confirmed = 0, best_tried = 0;
  const Trial* used = nullptr;
  const CameraHypothesis* answer = nullptr;
  for (const auto& q : order) {
    if (tried >= options_.fusion_hypotheses) break;
    const CameraHypothesis& h = hyp(q);
    ++tried;
    ViewPose p;
    p.ok = true;
    p.R = h.R, p.t = h.t;
    p.camera = CameraMatrix(K, h.R, h.t);
    p.centre_m = -(h.R.t() * h.t);
    outline_.Fit(*maps, K, lifter_, options_.fusion_radii, &p);
    const GuidedRefinement g = refiner_.Refine(gray, K, lifter_, {}, {}, &p);
    if (g.refined && g.inliers > best_confirmed) best_confirmed = g.inliers, best_tried = g.tried;
    if (g.refined && g.inliers >= options_.fusion_min_confirmed &&
        g.inliers >= options_.fusion_min_confirmed_share * g.tried) {
      used = &trials[std::size_t(q.trial)];
      answer = &h;
      r.pose = p;
      r.refinement = g;
      break;
    }
  }
  r.pose_ms = tm.ElapsedMs();
  int best_features = 0;
  for (const Trial& t : trials)
    for (const CameraHypothesis& h : t.hyps) best_features = std::max(best_features, h.features);
  if (!answer) {
    r.pose = {};
    r.pose.reason = cv::format(
        "fusion: %d camera hypotheses tried (best: %d view features agree, %d needed), none confirmed by the nadir "
        "photo's texture (best %d of %d corners, %d and %.0f %% needed)",
        tried, best_features, options_.fusion_min_features, best_confirmed, best_tried,
        options_.fusion_min_confirmed, 100 * options_.fusion_min_confirmed_share);
  } else {
    // the agreeing pairs, and which of them the final camera explains
    r.fusion_tilt = used->tilt;
    r.fusion_features = answer->features;
    r.fusion_rois = used->rois, r.fusion_lists = used->lists;
    r.fusion_match = used->stats;
    double ss = 0;
    for (std::size_t i = 0; i < used->X.size(); ++i) {
      if (!answer->agree[i]) continue;
      r.world.push_back(used->X[i]);
      r.matches.push_back(used->lifted[i]);
      const cv::Vec3d u = r.pose.camera * cv::Vec4d(used->X[i].x, used->X[i].y, used->X[i].z, 1);
      const double e = u[2] > 0 ? std::hypot(u[0] / u[2] - used->px[i].x, u[1] / u[2] - used->px[i].y) : 1e9;
      const bool in = e <= options_.fusion_consensus.agree_px;
      r.pose.inlier.push_back(char(in));
      if (in) ++r.pose.inliers, ss += e * e;
    }
    r.pose.matches = int(r.matches.size());
    r.pose.rms_px = r.pose.inliers ? std::sqrt(ss / r.pose.inliers) : 0;
    r.pose.reason = cv::format("fusion: %d view features agree (tilt hypothesis %.0f deg), confirmed by %d of %d corners "
                               "of the nadir photo, RMS %.2f px",
                               answer->features, used->tilt, r.refinement.inliers, r.refinement.tried,
                               r.refinement.rms_px);
  }
  if (!answer && !trials.empty()) {
    const Trial& t = trials.front();
    r.fusion_rois = t.rois, r.fusion_lists = t.lists, r.fusion_match = t.stats;
  }
  r.fusion_tried = tried;
  r.fusion_ms = r.match_ms + r.pose_ms;
  *out = std::move(r);
}

ViewRegistration ViewRegistrar::Register(const cv::Mat& view, const cv::Matx33d& K, const cv::Mat& view_color) const {
  Require(!view.empty(), ErrorCode::kInvalidArgument, "ViewRegistrar: an 8-bit grey or BGR view is required");
  const int longer = std::max(view.cols, view.rows);
  if (options_.max_view_px <= 0 || longer <= options_.max_view_px) return RegisterAt(view, K, view_color);
  // A large view is registered at a working resolution: the radii, windows
  // and scales of every step are in view pixels of the sizes it was built
  // for. The answer is given in the view's own pixels.
  const double k = double(options_.max_view_px) / longer;
  const cv::Size ws(std::max(1, int(std::lround(view.cols * k))), std::max(1, int(std::lround(view.rows * k))));
  cv::Mat v, c;
  cv::resize(view, v, ws, 0, 0, cv::INTER_AREA);
  if (!view_color.empty()) cv::resize(Colour(view_color, view), c, ws, 0, 0, cv::INTER_AREA);
  const double sx = double(ws.width) / view.cols, sy = double(ws.height) / view.rows;
  // pixel centres at integers: x' = sx (x + 0.5) - 0.5
  const cv::Matx33d S(sx, 0, 0.5 * sx - 0.5, 0, sy, 0.5 * sy - 0.5, 0, 0, 1), Si = S.inv();
  ViewRegistration r = RegisterAt(v, S * K, c);
  r.working_scale = std::sqrt(sx * sy);
  if (r.pose.ok) r.pose.camera = Si * r.pose.camera;  // K [R | t] = S^-1 (S K) [R | t]
  for (NadirMatch& m : r.matches) {
    const cv::Vec3d q = Si * cv::Vec3d(m.view.x, m.view.y, 1);
    m.view = cv::Point2f(float(q[0]), float(q[1]));  // an affine map of in-view points: bounded
  }
  r.pose.rms_px /= r.working_scale;
  return r;
}

ViewRegistration ViewRegistrar::RegisterAt(const cv::Mat& view, const cv::Matx33d& K, const cv::Mat& view_color) const {
  const cv::Mat gray = Gray(view);
  ViewRegistration r;
  Timer tm;
  const ViewMethod m = options_.method;
  if (m != ViewMethod::kFusion) {
    MatchTiles(gray, K, &r);
    if (r.pose.ok && options_.refine) {
      tm.Restart();
      std::vector<cv::Point2d> px;
      for (const auto& c : r.matches) px.emplace_back(c.view);
      r.refinement = refiner_.Refine(gray, K, lifter_, r.world, px, &r.pose);
      r.refine_ms = tm.ElapsedMs();
    }
  }
  if (m == ViewMethod::kFusion || (m == ViewMethod::kAuto && !r.pose.ok)) {
    ViewRegistration f;
    MatchFeatures(Colour(view_color, view), gray, K, &f);
    if (m == ViewMethod::kAuto) {
      f.mvkp_reason = r.pose.reason;
      f.match_ms += r.match_ms, f.pose_ms += r.pose_ms;  // the time both took
      if (!f.pose.ok) f.pose.reason += "; mvkp: " + r.pose.reason;
    }
    r = std::move(f);
  }
  if (r.pose.ok && options_.outline_refine) {
    tm.Restart();
    r.outline = outline_.Refine(gray, K, lifter_, &r.pose);
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
