// mvkp register-view / register-all: the camera of an oblique aerial view,
// through the nadir photo's registration to the LiDAR (issue 22, thesis §7.3;
// stage 2 after `mvkp register`). Method "mvkp": MVKP trained on the nadir
// photo's tiles finds the oblique view (oblique/nadir_tiles.h); the verified
// matches are lifted to 3-D through stage 1 and the camera follows by PnP +
// RANSAC (oblique/view_pose.h). register-all runs stage 1 and trains once,
// then registers every view.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "mvkp/buildings/depth_regions.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/geo/raster.h"
#include "mvkp/oblique/register_view.h"
#include "output.h"

namespace mvkp::cli {

namespace {

using Json = nlohmann::json;

cv::Matx33d ReadMatrix3(const Json& j, const std::string& what) {
  Require(j.is_array() && j.size() == 3, ErrorCode::kInvalidArgument, what + ": expected a 3x3 array");
  cv::Matx33d m;
  for (int r = 0; r < 3; ++r) {
    Require(j[size_t(r)].is_array() && j[size_t(r)].size() == 3, ErrorCode::kInvalidArgument,
            what + ": expected a 3x3 array");
    for (int c = 0; c < 3; ++c) {
      Require(j[size_t(r)][size_t(c)].is_number(), ErrorCode::kInvalidArgument, what + ": non-numeric entry");
      m(r, c) = j[size_t(r)][size_t(c)].get<double>();
      Require(std::isfinite(m(r, c)), ErrorCode::kInvalidArgument, what + ": non-finite entry");
    }
  }
  return m;
}

Json Mat(const auto& m, int rows, int cols) {
  Json a = Json::array();
  for (int r = 0; r < rows; ++r) {
    Json row = Json::array();
    for (int c = 0; c < cols; ++c) row.push_back(m(r, c));
    a.push_back(row);
  }
  return a;
}

// What both commands share.
struct Stage2Args {
  std::string method = "mvkp";
  double focal = 0, hfov = 50, res_m = 0;
  bool json = false;
  ViewRegistrarOptions reg;
};

struct RegisterViewArgs : Stage2Args {
  std::string depth, nadir, stage1, oblique, draw;
};

struct RegisterAllArgs : Stage2Args {
  std::string depth, nadir, stage1_in, stage1_out, draw_dir;
  bool correct_stage1 = true;
  std::vector<std::string> views;
};

// Stage 1's answer, checked against the inputs.
struct Stage1 {
  cv::Matx33d nadir_to_depth;
  cv::Point2d lean{0, 0};
  double res_m = 0;
};

Stage1 ParseStage1(const Json& s1, const std::string& name, const geo::DepthRaster& d, const std::string& depth_name,
                   const cv::Mat& nadir, const std::string& nadir_name, double res_arg) {
  Require(s1.is_object() && s1.contains("homography"), ErrorCode::kInvalidArgument,
          name + ": no \"homography\" (expected the output of mvkp register --json)");
  Require(!s1["homography"].is_null(), ErrorCode::kInvalidArgument,
          name + ": stage 1 found no registration of the nadir photo; register it first");
  Stage1 r;
  r.nadir_to_depth = ReadMatrix3(s1["homography"], name + " homography");
  if (s1.contains("lean_depth_px_per_m") && !s1["lean_depth_px_per_m"].is_null()) {
    const Json& l = s1["lean_depth_px_per_m"];
    Require(l.is_array() && l.size() == 2 && l[0].is_number() && l[1].is_number(), ErrorCode::kInvalidArgument,
            name + ": \"lean_depth_px_per_m\" must be null or two numbers");
    r.lean = {l[0].get<double>(), l[1].get<double>()};
  }
  auto size_of = [&](const char* key) -> cv::Size {
    if (!s1.contains(key) || !s1[key].is_object() || !s1[key].contains("size") || !s1[key]["size"].is_array() ||
        s1[key]["size"].size() != 2 || !s1[key]["size"][0].is_number_integer() ||
        !s1[key]["size"][1].is_number_integer())
      return {};
    return {s1[key]["size"][0].get<int>(), s1[key]["size"][1].get<int>()};
  };
  const cv::Size ds = size_of("depth"), ps = size_of("photo");
  Require(ds == cv::Size() || ds == d.z.size(), ErrorCode::kInvalidArgument,
          cv::format("%s does not match %s: it registered a %dx%d depth raster, this one is %dx%d", name.c_str(),
                     depth_name.c_str(), ds.width, ds.height, d.z.cols, d.z.rows));
  Require(ps == cv::Size() || ps == nadir.size(), ErrorCode::kInvalidArgument,
          cv::format("%s does not match %s: it registered a %dx%d photo, this one is %dx%d", name.c_str(),
                     nadir_name.c_str(), ps.width, ps.height, nadir.cols, nadir.rows));
  r.res_m = res_arg;
  if (r.res_m <= 0 && s1.contains("depth") && s1["depth"].is_object() && s1["depth"].contains("res_m") &&
      s1["depth"]["res_m"].is_number())
    r.res_m = s1["depth"]["res_m"].get<double>();
  if (r.res_m <= 0) r.res_m = d.res_m;
  Require(r.res_m > 0, ErrorCode::kInvalidArgument,
          depth_name + ": its ground resolution is unknown (no georeference); pass --res METRES");
  return r;
}

// Fusion's vegetation map needs colour (decoded besides the grey image that
// MVKP and the refinements see, so that every method sees the same grey).
cv::Mat LoadColour(const std::string& path, ViewMethod m) {
  return m == ViewMethod::kMvkp ? cv::Mat() : LoadImageColor(path);
}

Json ReadJsonFile(const std::string& path) {
  std::ifstream f(path);
  Require(bool(f), ErrorCode::kIo, path + ": cannot read");
  try {
    Json j;
    f >> j;
    return j;
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, path + ": not JSON (expected the output of mvkp register --json)");
  }
}

// The depth raster and the registrar (tiles trained once, lifter):
// everything a view's registration needs.
class Stage2 {
 public:
  Stage2(const geo::DepthRaster& d, const cv::Mat& nadir, const cv::Mat& nadir_colour, const Stage1& s1,
         const Stage2Args& a)
      : d_(d), s1_(s1), a_(a), reg_(d.z, s1.res_m, nadir, s1.nadir_to_depth, s1.lean, a.reg, nadir_colour) {}

  double train_ms() const { return reg_.train_ms(); }

  // One view's registration with what its JSON answer needs.
  struct Run {
    ViewRegistration r;
    cv::Matx33d K, nadir_to_depth;  // the stage 1 it was registered through
    double read_ms = 0, total_ms = 0;
  };
  Run Compute(const std::string& view_path) const {
    Timer total;
    Run run;
    const cv::Mat view = LoadImageGray(view_path), colour = LoadColour(view_path, a_.reg.method);
    run.K = ViewIntrinsics(view.size(), a_.hfov, a_.focal);
    run.read_ms = total.ElapsedMs();
    run.r = reg_.Register(view, run.K, colour);
    run.nadir_to_depth = reg_.nadir_to_depth();
    run.total_ms = total.ElapsedMs();
    return run;
  }

  // Stage 1 replaced (the tiles kept): later views are registered through it.
  void Restage(const cv::Matx33d& nadir_to_depth) { reg_.Restage(nadir_to_depth, s1_.lean); }
  const cv::Matx33d& nadir_to_depth() const { return reg_.nadir_to_depth(); }

  // The view's camera as the JSON answer; `draw`: the view with the LiDAR's
  // building outlines reprojected ("" for none).
  Json Register(const std::string& view_path, const std::string& draw) const {
    return Answer(view_path, Compute(view_path), draw);
  }

  Json Answer(const std::string& view_path, const Run& run, const std::string& draw) const {
    const ViewRegistration& r = run.r;
    const cv::Matx33d& K = run.K;
    const double read_ms = run.read_ms;
    const ViewPose& p = r.pose;
    const double res = s1_.res_m, z0 = reg_.lifter().ground_height();
    Json out;
    out["method"] = r.method == ViewMethod::kFusion ? "fusion-pnp" : "mvkp-pnp";  // what answered
    out["requested_method"] = ViewMethodName(a_.reg.method);
    out["view"] = view_path;
    out["ok"] = p.ok;
    out["reason"] = p.ok ? p.reason : "no registration: " + p.reason;
    out["K"] = Mat(K, 3, 3);
    out["world_frame"] = "metres east-north-up: x = depth column * res_m, y = -depth row * res_m, z = DSM height";
    out["res_m"] = res;
    if (p.ok) {
      out["camera"] = Mat(p.camera, 3, 4);
      out["R"] = Mat(p.R, 3, 3);
      out["centre_m"] = {p.centre_m[0], p.centre_m[1], p.centre_m[2]};
      const cv::Matx33d G = GroundHomography(p.camera, res, z0);
      out["ground_z_m"] = z0;
      out["ground_homography"] = Mat(G, 3, 3);  // depth px at the ground height -> view px
      out["homography"] = Mat(G * run.nadir_to_depth, 3, 3);  // nadir px -> view px, for the ground plane
    } else {
      out["camera"] = nullptr;
      out["homography"] = nullptr;
    }
    Json mj = Json::array();
    for (size_t k = 0; k < r.matches.size(); ++k) {
      const auto& c = r.matches[k];
      mj.push_back({c.nadir.x, c.nadir.y, c.view.x, c.view.y, c.distance, p.ok && p.inlier[k] ? 1 : 0});
    }
    out["matches"] = mj;
    out["inlier_tiles"] = r.inlier_tiles;
    out["inlier_cells"] = r.inlier_cells;  // of the view's 4 x 4
    out["inlier_height_span_m"] = r.inlier_height_span_m;
    out["tiles"] = reg_.tiles();
    out["nadir_gsd_m"] = reg_.nadir_gsd_m();
    out["lifted"] = r.matches.size();
    out["inliers"] = p.inliers;
    out["rms_px"] = p.rms_px;
    out["scale"] = r.scale;
    out["working_scale"] = r.working_scale;  // working px per view px (--max-view-px)
    const GuidedRefinement& g = r.refinement;
    out["refinement"] = {{"refined", g.refined}, {"tried", g.tried},   {"found", g.found},
                         {"inliers", g.inliers}, {"rms_px", g.rms_px}, {"shift_px", g.shift_px}};
    const OutlineRefinement& ol = r.outline;
    out["outline_refinement"] = {{"ran", ol.ran},     {"replaced", ol.replaced}, {"visible", ol.visible},
                                 {"pairs", ol.pairs}, {"first_pairs", ol.first_pairs},
                                 {"move_px", ol.move_px}};
    if (r.fusion_ran) {
      out["fusion"] = {{"view_regions", r.fusion_rois},
                       {"view_lists", r.fusion_lists},
                       {"nadir_regions", reg_.nadir_fusion().rois},
                       {"nadir_lists", reg_.nadir_fusion().oels},
                       {"region_matches", r.fusion_match.region_matches},
                       {"list_matches", r.fusion_match.list_matches},
                       {"agreeing_features", r.fusion_features},
                       {"tilt_hypothesis", r.fusion_tilt},
                       {"hypotheses_tried", r.fusion_tried},
                       {"confirmed_by", r.refinement.inliers},
                       {"mvkp_reason", r.mvkp_reason},
                       {"ms", r.fusion_ms}};
    }
    out["time_ms"] = {{"read", read_ms},
                      {"match", r.match_ms},
                      {"pose", r.pose_ms},
                      {"refine", r.refine_ms},
                      {"outline", r.outline_ms},
                      {"total", run.total_ms}};
    if (!draw.empty()) SaveImage(draw, Draw(view_path, p));
    return out;
  }

 private:
  // The LiDAR's building outlines, at their roof heights, in the view.
  cv::Mat Draw(const std::string& view_path, const ViewPose& p) const {
    cv::Mat img = LoadImageColor(view_path);
    if (!p.ok) return img;
    const double res = s1_.res_m;
    if (!outlines_) outlines_ = SegmentDepth(d_.z);  // once for all the views drawn
    for (const auto& r : *outlines_) {
      std::vector<cv::Point> poly;
      for (const auto& q : r.contour) {
        float z = -1e9f;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int yy = std::clamp(q.y + dy, 0, d_.z.rows - 1), xx = std::clamp(q.x + dx, 0, d_.z.cols - 1);
            if (std::isfinite(d_.z(yy, xx))) z = std::max(z, d_.z(yy, xx));
          }
        if (z < -1e8f) continue;
        const cv::Vec3d v = p.camera * cv::Vec4d(q.x * res, -q.y * res, z, 1);
        if (v[2] > 0) poly.emplace_back(int(std::lround(v[0] / v[2])), int(std::lround(v[1] / v[2])));
      }
      if (poly.size() >= 3) cv::polylines(img, std::vector<std::vector<cv::Point>>{poly}, true, {0, 0, 255}, 2);
    }
    return img;
  }

  const geo::DepthRaster& d_;
  Stage1 s1_;
  const Stage2Args& a_;
  ViewRegistrar reg_;  // Restage changes its stage 1
  mutable std::optional<std::vector<BuildingRegion>> outlines_;  // the depth's building regions, for Draw
};

void CheckStage2(Stage2Args& a) {
  a.reg.method = a.method == "fusion" ? ViewMethod::kFusion : a.method == "auto" ? ViewMethod::kAuto : ViewMethod::kMvkp;
  Require(a.method == ViewMethodName(a.reg.method), ErrorCode::kInvalidArgument,
          "--method must be mvkp, fusion or auto");
  a.reg.Check();
}

int RunRegisterView(RegisterViewArgs& a) {
  CheckStage2(a);
  const Json s1j = ReadJsonFile(a.stage1);
  const geo::DepthRaster d = geo::ReadDepthRaster(a.depth, geo::DepthReadOptions{});
  const cv::Mat nadir = LoadImageGray(a.nadir), nadir_colour = LoadColour(a.nadir, a.reg.method);
  LoadImageGray(a.oblique);  // a bad view is an error before the training
  const Stage1 s1 = ParseStage1(s1j, a.stage1, d, a.depth, nadir, a.nadir, a.res_m);
  const Stage2 stage2(d, nadir, nadir_colour, s1, a);
  Json out = stage2.Register(a.oblique, a.draw);
  out["time_ms"]["train"] = stage2.train_ms();
  if (a.json) {
    std::cout << out.dump() << std::endl;
  } else {
    std::printf("%s -> %s: %s; %s; train %.0f ms, view %.0f ms\n", a.nadir.c_str(), a.oblique.c_str(),
                out["ok"].get<bool>() ? "camera found" : "no camera", out["reason"].get<std::string>().c_str(),
                stage2.train_ms(), out["time_ms"]["total"].get<double>());
  }
  return 0;
}

int RunRegisterAll(RegisterAllArgs& a) {
  CheckStage2(a);
  Timer total;
  const geo::DepthRaster d = geo::ReadDepthRaster(a.depth, geo::DepthReadOptions{});
  const cv::Mat nadir = LoadImageGray(a.nadir), nadir_colour = LoadColour(a.nadir, a.reg.method);
  for (const auto& v : a.views) LoadImageGray(v);  // bad views are errors before the work
  if (!a.draw_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.draw_dir, ec);
    Require(!ec, ErrorCode::kIo, a.draw_dir + ": cannot create: " + ec.message());
  }
  Timer tm;
  const Json s1j = a.stage1_in.empty() ? RegisterNadir(a.depth, a.nadir, a.res_m) : ReadJsonFile(a.stage1_in);
  const double stage1_ms = a.stage1_in.empty() ? tm.ElapsedMs() : 0;
  if (!a.stage1_out.empty()) {
    std::ofstream f(a.stage1_out);
    Require(bool(f << s1j.dump() << '\n'), ErrorCode::kIo, a.stage1_out + ": cannot write");
  }
  Json out;
  out["method"] = "mvkp-register-all";
  out["stage1"] = {{"ok", s1j.value("ok", !s1j.value("homography", Json()).is_null())},
                   {"reason", s1j.value("reason", std::string())},
                   {"homography", s1j.value("homography", Json())},
                   {"lean_depth_px_per_m", s1j.value("lean_depth_px_per_m", Json())},
                   {"time_ms", stage1_ms}};
  Json views = Json::array();
  double train_ms = 0;
  const bool registered = s1j.is_object() && s1j.contains("homography") && !s1j["homography"].is_null();
  if (!registered) {
    // No nadir registration: no view can be placed (an answer, not an error).
    for (const auto& v : a.views)
      views.push_back({{"view", v}, {"ok", false}, {"camera", nullptr}, {"homography", nullptr},
                       {"reason", "no registration: stage 1 did not register the nadir photo"}});
  } else {
    const Stage1 s1 = ParseStage1(s1j, a.stage1_in.empty() ? "stage 1" : a.stage1_in, d, a.depth, nadir, a.nadir,
                                  a.res_m);
    Stage2 stage2(d, nadir, nadir_colour, s1, a);
    train_ms = stage2.train_ms();
    std::vector<Stage2::Run> runs;
    for (const auto& v : a.views) runs.push_back(stage2.Compute(v));
    // Stage 1 corrected by the views: when the LiDAR's outlines replaced the
    // cameras of at least two views, their pairs tell where stage 1 put the
    // nadir photo wrong; every view is then registered again through the
    // corrected stage 1 (a view keeps its first answer when the second
    // finds no camera).
    Json corr = {{"applied", false}};
    if (a.correct_stage1) {
      std::vector<ViewRegistration> regs;
      for (const auto& r : runs) regs.push_back(r.r);
      cv::Matx33d C;
      int inl = 0;
      const bool ok = Stage1Correction(regs, s1.res_m, &C, &inl);
      corr["inliers"] = inl;
      if (ok) {
        const cv::Matx33d H = C * s1.nadir_to_depth;
        stage2.Restage(H);
        int changed = 0;
        for (std::size_t i = 0; i < runs.size(); ++i) {
          Stage2::Run second = stage2.Compute(a.views[i]);
          if (second.r.pose.ok || !runs[i].r.pose.ok) runs[i] = std::move(second), ++changed;
        }
        corr = {{"applied", true}, {"inliers", inl}, {"correction", Mat(C, 3, 3)}, {"homography", Mat(H, 3, 3)},
                {"views_reregistered", changed}};
      }
    }
    out["stage1"]["correction"] = corr;
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const std::string& v = a.views[i];
      std::string draw;
      if (!a.draw_dir.empty())
        draw = (std::filesystem::path(a.draw_dir) / (std::filesystem::path(v).stem().string() + "-registered.jpg")).string();
      views.push_back(stage2.Answer(v, runs[i], draw));
    }
  }
  out["views"] = views;
  out["time_ms"] = {{"stage1", stage1_ms}, {"train", train_ms}, {"total", total.ElapsedMs()}};
  if (a.json) {
    std::cout << out.dump() << std::endl;
  } else {
    std::printf("stage 1: %s\n", out["stage1"]["ok"].get<bool>() ? "registered" : out["stage1"]["reason"].get<std::string>().c_str());
    for (const auto& v : views)
      std::printf("%s: %s; %s\n", v["view"].get<std::string>().c_str(), v["ok"].get<bool>() ? "camera found" : "no camera",
                  v["reason"].get<std::string>().c_str());
    std::printf("stage 1 %.0f ms, training %.0f ms, total %.0f ms\n", stage1_ms, train_ms, total.ElapsedMs());
  }
  return 0;
}

void AddStage2Options(CLI::App* c, Stage2Args* a) {
  c->add_option("--method", a->method,
                "mvkp: MVKP trained on the nadir photo's tiles (thesis 7.3.1); fusion: regions and edgelet lists "
                "described by shape contexts (7.3.2); auto: mvkp, then fusion for a view mvkp finds no camera for")
      ->check(CLI::IsMember({"mvkp", "fusion", "auto"}))
      ->capture_default_str();
  c->add_option("--max-view-px", a->reg.max_view_px,
                "register a view whose longer side exceeds this resized to it; the answer is in its own pixels "
                "(0: never)")
      ->check(CLI::Range(0, 65536))
      ->capture_default_str();
  c->add_option("--fusion-tilts", a->reg.fusion_tilts,
                "fusion: tilts off nadir (degrees) the view is rectified for, in turn (an upright camera)")
      ->check(CLI::Range(0.0, 88.0))
      ->capture_default_str();
  c->add_option("--fusion-hypotheses", a->reg.fusion_hypotheses,
                "fusion: camera hypotheses fitted to the LiDAR outlines and checked against the nadir photo")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  c->add_option("--focal", a->focal, "focal length of the oblique camera, pixels (default: from --hfov)")
      ->check(CLI::Range(1.0, 1e6));
  c->add_option("--hfov", a->hfov, "horizontal field of view of the oblique camera, degrees")
      ->check(CLI::Range(5.0, 150.0))
      ->capture_default_str();
  c->add_option("--res", a->res_m, "depth raster cell size, metres (default: from stage 1 or the raster)")
      ->check(CLI::Range(0.01, 100.0));
  c->add_option("--min-inliers", a->reg.pose.min_inliers, "matches the camera must explain")
      ->check(CLI::Range(6, 100000))
      ->capture_default_str();
  c->add_option("--min-inlier-ratio", a->reg.pose.min_inlier_ratio, "share of the lifted matches the camera must explain")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  c->add_option("--tile", a->reg.tiles.tile_px, "side of the nadir photo's tiles trained by MVKP, pixels")
      ->check(CLI::Range(64, 4096))
      ->capture_default_str();
  c->add_option("--tile-stride", a->reg.tiles.stride, "step between tiles, share of --tile (< 1: they overlap)")
      ->check(CLI::Range(0.2, 1.0))
      ->capture_default_str();
  c->add_option("--tile-views", a->reg.tiles.train.views, "MVKP training views per tile")
      ->check(CLI::Range(10, 1000))
      ->capture_default_str();
  c->add_option("--tile-levels", a->reg.tiles.train.levels, "MVKP training pyramid levels per tile (0: auto)")
      ->check(CLI::Range(0, 8))
      ->capture_default_str();
  c->add_option("--nadir-gsd", a->reg.nadir_gsd_m,
                "train a nadir photo finer than this (metres per pixel, from stage 1) resized to it (0: never)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  c->add_option("--max-height-step", a->reg.max_height_step_m,
                 "drop pairs whose nadir point lies within --step-radius tile pixels of a height step above this, "
                 "metres (0: keep all)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  c->add_option("--step-radius", a->reg.step_radius_px, "radius of the height-step test, pixels of the nadir tiles")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  c->add_option("--scales", a->reg.scales, "scales the view is searched at, in turn, until a camera is found")
      ->check(CLI::Range(0.05, 4.0))
      ->capture_default_str();
  c->add_flag("!--no-refine", a->reg.refine,
              "keep the camera from the tiles' matches (default: refine it against the whole nadir photo by "
              "correlation at the corners it predicts)");
  c->add_flag("!--no-outline-refine", a->reg.outline_refine,
              "keep the camera from the nadir photo (default: refit it to the LiDAR's roof outlines seen as edges "
              "in the view, and take the refit when it moves them by more than --outline-keep pixels)");
  c->add_option("--outline-keep", a->reg.outline.keep_px,
                "outline refit move (median, view px) above which it replaces the camera")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  c->add_option("--outline-gain", a->reg.outline.min_gain,
                "outline points the refit must pair, relative to the camera it replaces")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  c->add_option("--outline-radii", a->reg.outline.radii, "pairing radius of each outline refit round, view px")
      ->check(CLI::Range(0.5, 64.0))
      ->capture_default_str();
  c->add_option("--refine-ncc", a->reg.guided.min_ncc, "correlation a refinement match needs")
      ->check(CLI::Range(0.05, 0.99))
      ->capture_default_str();
  c->add_option("--refine-search", a->reg.guided.search_px, "refinement search radius around the prediction, view px")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  c->add_flag("--json", a->json, "print the camera(s) and the correspondences as JSON");
}

}  // namespace

void RegisterRegisterView(CLI::App& app, int* code) {
  auto a = std::make_shared<RegisterViewArgs>();
  auto* c = app.add_subcommand(
      "register-view",
      "Stage 2 (issue 22): the camera of an oblique view OBLIQUE of the area of NADIR, through NADIR's "
      "registration to DEPTH (STAGE1 = the output of mvkp register DEPTH NADIR --json). MVKP trained on "
      "NADIR's tiles finds OBLIQUE; its matches, lifted to 3-D through stage 1, give the camera by PnP + RANSAC");
  c->add_option("DEPTH", a->depth, "depth raster (as for mvkp register)")->required();
  c->add_option("NADIR", a->nadir, "the nadir photo registered by stage 1")->required();
  c->add_option("STAGE1", a->stage1, "mvkp register DEPTH NADIR --json output")->required();
  c->add_option("OBLIQUE", a->oblique, "the oblique view")->required();
  AddStage2Options(c, a.get());
  c->add_option("--draw", a->draw, "write the view with the LiDAR's building outlines reprojected");
  c->callback([a, code] { *code = RunRegisterView(*a); });
}

void RegisterRegisterAll(CLI::App& app, int* code) {
  auto a = std::make_shared<RegisterAllArgs>();
  auto* c = app.add_subcommand(
      "register-all",
      "Stages 1 and 2 (issue 22): register NADIR to DEPTH (as mvkp register), train MVKP on NADIR's tiles once, "
      "then give the camera of each oblique VIEW (as mvkp register-view)");
  c->add_option("DEPTH", a->depth, "depth raster (as for mvkp register)")->required();
  c->add_option("NADIR", a->nadir, "the nadir photo of the area")->required();
  c->add_option("VIEW", a->views, "oblique views")->required();
  AddStage2Options(c, a.get());
  c->add_option("--stage1", a->stage1_in, "use this stage-1 answer (mvkp register --json) instead of registering")
      ->check(CLI::ExistingFile);
  c->add_option("--save-stage1", a->stage1_out, "write the stage-1 answer (for register-view)");
  c->add_option("--draw-dir", a->draw_dir, "write each view with the LiDAR's building outlines reprojected here");
  c->add_flag("!--no-correct-stage1", a->correct_stage1,
              "keep stage 1 as given (default: when the LiDAR's outlines replaced the cameras of two or more views, "
              "correct stage 1 from their pairs and register every view again through it)");
  c->callback([a, code] { *code = RunRegisterAll(*a); });
}

}  // namespace mvkp::cli
