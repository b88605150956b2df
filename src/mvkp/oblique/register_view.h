// Stage 2 of aerial registration by MVKP (issue 22, thesis §7.3.1): the
// camera of an oblique view from the nadir photo's tiles (nadir_tiles.h),
// their matches lifted to 3-D through stage 1 (view_pose.h). What `mvkp
// register-view` / `register-all` and the Python ViewRegistrar run.
#pragma once

#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/oblique/fusion.h"
#include "mvkp/oblique/guided_refine.h"
#include "mvkp/oblique/nadir_tiles.h"
#include "mvkp/oblique/outline_refine.h"
#include "mvkp/oblique/rectify.h"
#include "mvkp/oblique/view_pose.h"

namespace mvkp {

// How a view is matched to the nadir photo: MVKP tiles (thesis §7.3.1),
// feature fusion (§7.3.2, fusion.h), or auto: MVKP, and fusion only for a
// view MVKP finds no camera for (MVKP is faster and, on the views both
// register, more accurate; see docs/oblique.md).
enum class ViewMethod { kMvkp, kFusion, kAuto };
const char* ViewMethodName(ViewMethod m);

struct ViewRegistrarOptions {
  ViewMethod method = ViewMethod::kMvkp;
  // A view whose longer side exceeds this is registered area-resized to it
  // (radii, windows and scales below are in view pixels of 640-1600 px
  // views); the camera and the matches are given in the view's own pixels.
  // A 4096 x 3072 copy of a 1024 x 768 view: found at 1600 px, not at full
  // size by either method (and fusion's edge maps took 0.8 GB). 0: never.
  int max_view_px = 1600;
  NadirTilesOptions tiles;
  ViewPoseOptions pose;
  // The view is searched at each scale in turn (area-averaged) until a camera
  // is found: views show the ground 0.15-0.6 m per pixel, the photo 0.4 m or
  // coarser.
  std::vector<double> scales = {1.0, 0.5, 0.3};
  // A nadir photo finer than this (metres per pixel at its centre, from stage
  // 1) is tiled resized to it: training on the tuning set 209 -> 103 s, and
  // 94 views right instead of 88. 0: never.
  double nadir_gsd_m = 0.4;
  // Feature selection against 3-D change (thesis §7.3.1): a pair is not
  // lifted when the DSM within step_radius_px pixels (of the tiles) of its
  // nadir point spans more than max_height_step_m (a roof edge, a wall, a
  // tree): there a point placed one pixel off takes another surface's
  // height, and a coarse photo's pixel is metres wide. Tuning seeds 1, 3, 4
  // (108 views): 95 right, 1 wrong -> 96 right, 0 wrong (1 m: 93 right;
  // a 2 px radius: 92 right, 1 wrong). 0: keep all.
  double max_height_step_m = 2.0;
  double step_radius_px = 1.0;
  // The camera found is refined against the whole nadir photo
  // (guided_refine.h) when `refine`.
  bool refine = true;
  GuidedRefineOptions guided;
  // Then against the LiDAR's own roof outlines (outline_refine.h), which
  // corrects a camera that a stage-1 error displaced, when `outline_refine`.
  bool outline_refine = true;
  OutlineRefineOptions outline;
  // Feature fusion (fusion.h): its features; the view rectified to a
  // pseudo-nadir view (rectify.h) for each of fusion_tilts (degrees off
  // nadir; empty: the view as it is); the camera hypotheses of its feature
  // pairs (FeatureHypotheses), the fusion_hypotheses best of all tilts
  // with at least fusion_min_features agreeing view features tried in
  // turn: each fitted to the LiDAR's roof outlines over fusion_radii
  // (outline_refine.h, the global context that propagates one feature
  // pair's camera to the whole view), then refined against the nadir
  // photo (guided_refine.h), which must confirm it with at least
  // fusion_min_confirmed of its corners found by correlation where the
  // camera predicts them; the shapes alone do not tell a right camera from
  // a chance one.
  FusionOptions fusion;
  std::vector<double> fusion_tilts = {35, 45, 55};
  RectifyOptions rectify;
  FeatureConsensusOptions fusion_consensus;
  int fusion_seeds = 300;        // camera hypotheses per tilt (one per feature pair, best first)
  double fusion_score_px = 6;    // ranked by OutlineRefiner::Score at this radius ...
  int fusion_min_outline = 100;  // ... over at least this many outline points in the view
  int fusion_hypotheses = 8;     // the best ones fitted and checked
  int fusion_min_features = 1;
  std::vector<double> fusion_radii = {24, 16, 10, 6, 4, 3, 2};
  int fusion_min_confirmed = 40;
  // ... and they must be at least this share of the corners it predicted
  // (visible, textured): a right camera's predictions land on their
  // corners (fusion answers on tuning seed 1: 21-85 %, the two lowest 1.5
  // and 2.2 px off), a chance camera confirms a few near repeated texture
  // (the one wrong answer on held-back seed 114: 42 of 428, 10 %, 11.5 px
  // off).
  double fusion_min_confirmed_share = 0.15;
  // A fusion point is lifted to the highest surface within this many metres
  // of it: outlines and edgelets lie on roof edges, and the top of a step is
  // what every view sees.
  double fusion_lift_m = 1.0;
  void Check() const;  // throws Error(kInvalidArgument)
};

struct ViewRegistration {
  ViewMethod method = ViewMethod::kMvkp;  // the method whose answer this is
  ViewPose pose;                     // pose.ok: a camera; else pose.reason says why not
  std::vector<NadirMatch> matches;   // the lifted pairs PnP saw (pose.inlier flags them)
  std::vector<cv::Point3d> world;    // their 3-D points
  double scale = 0;                  // the view scale that answered (or came closest)
  double match_ms = 0, pose_ms = 0;
  int inlier_tiles = 0, inlier_cells = 0;  // where the agreeing pairs come from
  double inlier_height_span_m = 0;
  GuidedRefinement refinement;       // what the guided refinement did
  double refine_ms = 0;
  OutlineRefinement outline;         // what the outline refinement did
  double outline_ms = 0;
  // feature fusion, when it ran (method fusion, or auto after MVKP found nothing)
  bool fusion_ran = false;
  int fusion_rois = 0, fusion_lists = 0;  // the view's regions and edgelet lists
  int fusion_features = 0;                // view features agreeing on the camera
  double fusion_tilt = -1;                // the tilt hypothesis that answered (-1: none, the view as it is)
  int fusion_tried = 0;                   // camera hypotheses fitted and checked
  FusionMatchStats fusion_match;
  double fusion_ms = 0;                   // features, matching and fit
  std::string mvkp_reason;                // auto: why MVKP found no camera
  double working_scale = 1;               // working px per view px (options.max_view_px)
};

class ViewRegistrar {
 public:
  // `nadir` 8-bit grey or BGR (MVKP and the refinements see it grey);
  // `nadir_color` (optional, BGR): the same photo in colour for fusion's
  // vegetation map, when `nadir` is the grey decode of it; stage 1:
  // `nadir_to_depth` (nadir px -> depth px) and `lean_px_per_m` (depth px
  // per metre of height); `depth` the DSM (metres, NaN no return) with cell
  // size `res_m`. Trains the tiles (method mvkp, auto) and describes the
  // photo's fusion features (fusion, auto).
  ViewRegistrar(const cv::Mat1f& depth, double res_m, const cv::Mat& nadir, const cv::Matx33d& nadir_to_depth,
                cv::Point2d lean_px_per_m, const ViewRegistrarOptions& options = {}, const cv::Mat& nadir_color = {});

  // The camera of an 8-bit grey or BGR view with intrinsics K (no
  // distortion), by options.method; `view_color` (optional, BGR) as
  // nadir_color above.
  ViewRegistration Register(const cv::Mat& view, const cv::Matx33d& K, const cv::Mat& view_color = {}) const;

  // Replaces stage 1 (as at construction), keeping the trained tiles: what
  // a correction of stage 1 by the views (Stage1Correction) needs.
  void Restage(const cv::Matx33d& nadir_to_depth, cv::Point2d lean_px_per_m);
  const cv::Matx33d& nadir_to_depth() const { return nadir_to_depth_; }

  // the tiles' training and the nadir photo's fusion features (the methods' share)
  double train_ms() const { return (tiles_ ? tiles_->train_ms() : 0.0) + fusion_train_ms_; }
  double nadir_gsd_m() const { return nadir_gsd_m_; }   // of the photo given
  std::size_t tiles() const { return tiles_ ? tiles_->size() : 0; }  // 0 for method fusion
  // The nadir photo's fusion features (empty for method mvkp) and their time.
  const FusionFeatures& nadir_fusion() const { return nadir_fusion_; }
  const NadirLifter& lifter() const { return lifter_; }

 private:
  ViewRegistration RegisterAt(const cv::Mat& view, const cv::Matx33d& K, const cv::Mat& view_color) const;
  void MatchTiles(const cv::Mat& gray, const cv::Matx33d& K, ViewRegistration* r) const;
  void MatchFeatures(const cv::Mat& view, const cv::Mat& gray, const cv::Matx33d& K, ViewRegistration* r) const;
  bool LiftTop(cv::Point2d p, cv::Point3d* world) const;

  ViewRegistrarOptions options_;
  cv::Mat1f depth_;   // kept for Restage
  cv::Mat nadir_;
  double res_m_;
  cv::Matx33d nadir_to_depth_;
  double nadir_gsd_m_;
  std::optional<NadirTiles> tiles_;  // not trained for method fusion
  NadirLifter lifter_;
  GuidedRefiner refiner_;
  OutlineRefiner outline_;
  FusionFeatures nadir_fusion_;
  double fusion_train_ms_ = 0;
};

// Stage 1 corrected by the views whose camera the LiDAR's outlines replaced
// (outline_refine.h): each of their agreeing pairs was lifted through stage
// 1 to a depth pixel, while the replaced camera sees its view pixel at
// another point of the same horizontal plane. A similarity of the depth
// plane (depth px -> depth px) is fitted to these by RANSAC (`ransac_px`,
// depth px); the corrected stage 1 is C * nadir_to_depth. False (C
// untouched) with fewer than `min_inliers` agreeing pairs, or fewer than
// `min_views` replaced views among them.
struct Stage1CorrectionOptions {
  double ransac_px = 1.0;
  int min_inliers = 30;
  int min_views = 2;
};
bool Stage1Correction(const std::vector<ViewRegistration>& views, double res_m, cv::Matx33d* C,
                      int* inliers = nullptr, const Stage1CorrectionOptions& options = {});

// Ground metres per nadir pixel at the centre of a photo of `size`, from
// stage 1's homography and the depth cell size.
double NadirGsd(cv::Size size, const cv::Matx33d& nadir_to_depth, double res_m);

// A pinhole K for a view of `size` with horizontal field of view `hfov_deg`
// (or focal length `focal_px` when > 0), principal point at the centre.
cv::Matx33d ViewIntrinsics(cv::Size size, double hfov_deg, double focal_px = 0);

}  // namespace mvkp
