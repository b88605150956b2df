#include "output.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp::cli {

void AddTrainOptions(CLI::App* cmd, TrainOptions* o) {
  cmd->add_option("--views", o->views, "synthetic affine training views")->capture_default_str();
  cmd->add_option("--locations", o->locations, "object locations kept (most stable first)")->capture_default_str();
  cmd->add_option("--clusters", o->clusters, "k-means centres per location")->capture_default_str();
  cmd->add_option("--kernels", o->kernels, "Walsh-Hadamard kernels (descriptor dimension)")->capture_default_str();
  cmd->add_option("--seed", o->seed, "random seed (views, noise, k-means)")->capture_default_str();
  cmd->add_option("--min-scale", o->min_scale, "smallest view scale lambda")->capture_default_str();
  cmd->add_option("--max-scale", o->max_scale, "largest view scale lambda")->capture_default_str();
  cmd->add_option("--points-per-view", o->points_per_view, "detections kept per training view")->capture_default_str();
  cmd->add_option("--max-object-side", o->max_object_side, "train larger targets at this size (0: never)")->capture_default_str();
  const std::map<std::string, ViewModel> vm = {
      {"mixed", ViewModel::kMixed}, {"camera", ViewModel::kCamera}, {"affine", ViewModel::kAffine}};
  cmd->add_option("--view-model", o->view_model,
                  "training views: mixed (affine + steep camera views) | camera (tilted plane only) | affine (thesis)")
      ->transform(CLI::CheckedTransformer(vm, CLI::ignore_case))
      ->default_str("mixed");
  cmd->add_option("--camera-views", o->camera_views, "mixed: pinhole-camera views per level at steep tilts")->capture_default_str();
  cmd->add_option("--camera-min-tilt", o->camera_min_tilt, "mixed: shallowest tilt of the camera views (degrees)")->capture_default_str();
  cmd->add_option("--levels", o->levels, "training pyramid levels, a factor 2 apart (0: auto)")->capture_default_str();
  cmd->add_option("--min-apparent-size", o->min_apparent_size, "auto levels cover targets down to this longest side (px)")
      ->capture_default_str();
  cmd->add_option("--level-locations", o->level_locations, "each smaller level keeps this fraction of the previous level's locations")
      ->capture_default_str();
  cmd->add_option("--level-min-scale", o->level_min_scale, "camera views: smallest scale of a level")->capture_default_str();
  cmd->add_option("--level-max-scale", o->level_max_scale, "camera views: largest scale of a level")->capture_default_str();
  cmd->add_option("--max-tilt", o->max_tilt_deg, "camera views: steepest tilt (degrees)")->capture_default_str();
  cmd->add_option("--frontal-share", o->frontal_share, "camera views: share at tilts <= 40 degrees")->capture_default_str();
  cmd->add_option("--view-blur", o->view_blur, "max Gaussian blur sigma of training views")->capture_default_str();
  cmd->add_option("--view-noise", o->view_noise, "noise sigma of training views (grey levels)")->capture_default_str();
  cmd->add_option("--track-radius", o->track_radius, "view pixels within which detections form one track")->capture_default_str();
  cmd->add_flag("!--no-orient", o->orient, "thesis-literal patches: no orientation normalisation");
  const std::map<std::string, Selection> sel = {{"rifs", Selection::kRifs}, {"stability", Selection::kStability}};
  cmd->add_option("--select", o->select, "rank view tracks by: rifs (SPEC 4) | stability")
      ->transform(CLI::CheckedTransformer(sel, CLI::ignore_case))
      ->default_str(SelectionName(o->select));
  cmd->add_option("--alpha", o->alpha, "RIFS weight of the ranking score, 0..1 (0 = stability only)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--keep",
         [o](const std::string& v) {
           // "N" locations or "P%" of the eligible view tracks.
           try {
             std::size_t used = 0;
             const double x = std::stod(v, &used);
             if (used == v.size() && x == std::floor(x) && x >= 1 && x <= 100000) {
               o->locations = int(x);
               o->keep_fraction = 0;
               return;
             }
             if (used + 1 == v.size() && v.back() == '%' && x > 0 && x <= 100) {
               o->keep_fraction = x / 100.0;
               return;
             }
           } catch (const std::exception&) {
           }
           throw CLI::ValidationError("--keep", "expected a count N (1..100000) or a percentage P% (0 < P <= 100), got '" + v + "'");
         },
         "keep N view tracks, or P% of the eligible ones (same as --locations N)")
      ->default_str(std::to_string(o->locations));
  cmd->add_option("--min-stability", o->min_stability, "L_SS: drop tracks seen in fewer views (0: auto)")
      ->capture_default_str();
  cmd->add_option("--rotation-views", o->rotation_views, "rotation-dominant views used only to score tracks")
      ->capture_default_str();
  using SV = TrainOptions::StatsViews;
  const std::map<std::string, SV> stats = {{"rotation", SV::kRotation}, {"general", SV::kGeneral}, {"all", SV::kAll}};
  cmd->add_option("--rifs-stats", o->stats_views, "views whose descriptors give DS and VS: all (SPEC 4) | rotation | general")
      ->transform(CLI::CheckedTransformer(stats, CLI::ignore_case))
      ->default_str("all");
}

void AddMatchOptions(CLI::App* cmd, MatchOptions* o, bool* affine) {
  cmd->add_option("--ratio", o->ratio, "distance-ratio threshold d1/d2")->capture_default_str();
  cmd->add_option("--dynamic-goal", o->dynamic_goal, "steer the ratio toward this many matches (0: fixed ratio)")->capture_default_str();
  cmd->add_option("--max-points", o->max_points, "strongest query points")->capture_default_str();
  cmd->add_option("--grid-cells", o->grid_cells, "query points: cells along the frame's longer side")->capture_default_str();
  cmd->add_option("--grid-share", o->grid_share, "share of the query points given out per cell first (0: strongest of the frame)")->capture_default_str();
  cmd->add_option("--half-res-points", o->half_res_points, "extra points detected at half resolution (0: off)")->capture_default_str();
  cmd->add_option("--ransac-threshold", o->ransac_threshold, "inlier reprojection error, pixels")->capture_default_str();
  cmd->add_option("--min-inliers", o->min_inliers, "fewer inliers: target not found")->capture_default_str();
  cmd->add_flag("--affine", *affine, "fit an affine transform instead of a homography");
  cmd->add_option("--index", o->index, "descriptor search: ivf (inverted file, approximate) | exact (FFVA) | approx | brute")
      ->check(CLI::IsMember({"ivf", "exact", "approx", "brute"}))
      ->capture_default_str();
  cmd->add_option("--nprobe", o->nprobe, "ivf: lists scanned per query descriptor")->capture_default_str();
  const std::map<std::string, RobustMethod> methods = {{"ransac", RobustMethod::kRansac}, {"fast", RobustMethod::kFast},
                                                       {"accurate", RobustMethod::kAccurate}, {"magsac", RobustMethod::kMagsac},
                                                       {"prosac", RobustMethod::kProsac}};
  cmd->add_option("--robust", o->robust, "robust estimator: ransac | fast | accurate | magsac | prosac")
      ->transform(CLI::CheckedTransformer(methods, CLI::ignore_case))
      ->default_str(o->robust == RobustMethod::kProsac ? "prosac" : "accurate");
  cmd->add_option("--first-pass-points", o->first_pass_points,
                  "search this many frame-spread points first; the rest only if that finds too few inliers (0: all)")
      ->capture_default_str();
  cmd->add_option("--steep-anisotropy", o->steep_anisotropy,
                  "found weakly at least this steep (cos tilt): also try the simulated tilts (0: off)")
      ->capture_default_str();
  cmd->add_option("--retry-below-inliers", o->retry_below_inliers, "found with fewer inliers: also search half resolution")
      ->capture_default_str();
  cmd->add_option("--upsample-points", o->upsample_points, "not found: points from the frame upsampled twice (0: off)")
      ->capture_default_str();
  cmd->add_option("--tilt-factors", o->tilt_factors, "steep views: tilt factors simulated when nothing is found (ASIFT-style)")
      ->delimiter(',');
  cmd->add_option("--tilt-directions", o->tilt_directions, "steep views: directions per tilt factor (0: off)")->capture_default_str();
  cmd->add_option("--tilt-directions-grow", o->tilt_directions_grow,
                  "steep views: larger tilt factors get proportionally more directions (ASIFT's spacing)")
      ->capture_default_str();
  cmd->add_option("--tilt-points", o->tilt_points, "steep views: query points per simulated view")->capture_default_str();
  cmd->add_flag("!--no-refine", o->refine, "skip the guided refinement after the robust fit");
  cmd->add_option("--refine-radius", o->refine_radius, "guided refinement: search radius (px)")->capture_default_str();
}

nlohmann::json HomographyJson(const MatchResult& r) {
  if (!r.found) return nullptr;
  nlohmann::json h = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) h.push_back({r.homography(i, 0), r.homography(i, 1), r.homography(i, 2)});
  return h;
}

nlohmann::json TimingJson(const MatchTiming& t) {
  return {{"detect", t.smooth_ms + t.detect_ms}, {"describe", t.describe_ms}, {"search", t.search_ms},
          {"verify", t.verify_ms}, {"query", t.total()}};
}

Model TrainNamed(const std::string& path, const cv::Mat& gray, const TrainOptions& options, TrainReport* report) {
  try {
    return Train(gray, options, report);
  } catch (const Error& e) {
    if (e.code() == ErrorCode::kNoTexture) throw Error(e.code(), path + ": " + e.what());
    throw;
  }
}

static cv::Mat ToBgr(const cv::Mat& m) {
  cv::Mat out;
  if (m.channels() == 1) cv::cvtColor(m, out, cv::COLOR_GRAY2BGR);
  else out = m.clone();
  return out;
}

static void DrawOutline(cv::Mat& img, const MatchResult& r, cv::Point2f offset) {
  if (!r.found) return;
  std::vector<cv::Point> poly;
  for (const auto& p : r.outline) poly.emplace_back(cv::Point(int(std::lround(p.x + offset.x)), int(std::lround(p.y + offset.y))));
  cv::polylines(img, poly, true, cv::Scalar(0, 255, 0), 3, cv::LINE_AA);
}

cv::Mat DrawMatch(const cv::Mat& frame, const MatchResult& r) {
  cv::Mat img = ToBgr(frame);
  for (const auto& m : r.matches)
    cv::circle(img, m.query, m.inlier ? 3 : 2, m.inlier ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255), -1, cv::LINE_AA);
  DrawOutline(img, r, {0, 0});
  cv::putText(img, r.found ? "found: " + std::to_string(r.inliers) + " inliers" : "not found", {10, 25},
              cv::FONT_HERSHEY_SIMPLEX, 0.7, r.found ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255), 2, cv::LINE_AA);
  return img;
}

cv::Mat DrawPair(const cv::Mat& object, const cv::Mat& frame, const MatchResult& r) {
  cv::Mat a = ToBgr(object), b = ToBgr(frame);
  cv::Mat img(std::max(a.rows, b.rows), a.cols + b.cols, CV_8UC3, cv::Scalar::all(0));
  a.copyTo(img(cv::Rect(0, 0, a.cols, a.rows)));
  b.copyTo(img(cv::Rect(a.cols, 0, b.cols, b.rows)));
  const cv::Point2f off(float(a.cols), 0.f);
  for (const auto& m : r.matches) {
    if (m.inlier) cv::line(img, m.object, m.query + off, cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
    else cv::circle(img, m.query + off, 2, cv::Scalar(0, 0, 255), -1, cv::LINE_AA);
  }
  DrawOutline(img, r, off);
  return img;
}

std::string IndexedPath(const std::string& path, int index, int count) {
  if (count <= 1) return path;
  std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + "-" + std::to_string(index) + p.extension().string())).string();
}

std::string Count(std::size_t n, const std::string& noun, const std::string& plural) {
  return std::to_string(n) + " " + (n == 1 ? noun : plural.empty() ? noun + "s" : plural);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
  return v[v.size() / 2];
}

void Progress(const std::string& what, int done, int total) {
  static const bool tty = isatty(fileno(stderr));
  if (!tty) return;
  std::fprintf(stderr, "\r%s %d/%d%s", what.c_str(), done, total, done == total ? "\n" : "");
  std::fflush(stderr);
}

}  // namespace mvkp::cli
