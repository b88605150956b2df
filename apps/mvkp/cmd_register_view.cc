// mvkp register-view: the camera of an oblique aerial view, through the nadir
// photo's registration to the LiDAR (issue 22, thesis §7.3; stage 2 after
// `mvkp register`). Method "mvkp": MVKP trained on the nadir photo finds the
// oblique view; its verified matches are lifted to 3-D through stage 1 and
// the camera follows by PnP + RANSAC (oblique/view_pose.h).
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
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
#include "mvkp/match/matcher.h"
#include "mvkp/oblique/view_pose.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {

namespace {

using Json = nlohmann::json;

struct RegisterViewArgs {
  std::string depth, nadir, stage1, oblique, draw;
  double focal = 0, hfov = 50, res_m = 0;
  bool json = false;
  ViewPoseOptions pose;
};

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

int RunRegisterView(RegisterViewArgs& a) {
  Timer total;
  a.pose.Check();
  // stage 1: `mvkp register --json` of NADIR onto DEPTH
  Json s1;
  {
    std::ifstream f(a.stage1);
    Require(bool(f), ErrorCode::kIo, a.stage1 + ": cannot read");
    try {
      f >> s1;
    } catch (const std::exception&) {
      throw Error(ErrorCode::kInvalidArgument, a.stage1 + ": not JSON (expected the output of mvkp register --json)");
    }
  }
  Require(s1.is_object() && s1.contains("homography"), ErrorCode::kInvalidArgument,
          a.stage1 + ": no \"homography\" (expected the output of mvkp register --json)");
  Require(!s1["homography"].is_null(), ErrorCode::kInvalidArgument,
          a.stage1 + ": stage 1 found no registration of the nadir photo; register it first");
  const cv::Matx33d nadir_to_depth = ReadMatrix3(s1["homography"], a.stage1 + " homography");
  cv::Point2d lean(0, 0);
  if (s1.contains("lean_depth_px_per_m") && !s1["lean_depth_px_per_m"].is_null()) {
    const Json& l = s1["lean_depth_px_per_m"];
    Require(l.is_array() && l.size() == 2 && l[0].is_number() && l[1].is_number(), ErrorCode::kInvalidArgument,
            a.stage1 + ": \"lean_depth_px_per_m\" must be null or two numbers");
    lean = {l[0].get<double>(), l[1].get<double>()};
  }

  geo::DepthReadOptions ro;
  const geo::DepthRaster d = geo::ReadDepthRaster(a.depth, ro);
  const cv::Mat nadir = LoadImageGray(a.nadir);
  const cv::Mat oblique = LoadImageGray(a.oblique);
  auto size_of = [&](const char* key) -> cv::Size {
    if (!s1.contains(key) || !s1[key].is_object() || !s1[key].contains("size") || !s1[key]["size"].is_array() ||
        s1[key]["size"].size() != 2)
      return {};
    return {s1[key]["size"][0].get<int>(), s1[key]["size"][1].get<int>()};
  };
  const cv::Size ds = size_of("depth"), ps = size_of("photo");
  Require(ds == cv::Size() || ds == d.z.size(), ErrorCode::kInvalidArgument,
          cv::format("%s does not match %s: it registered a %dx%d depth raster, this one is %dx%d", a.stage1.c_str(),
                     a.depth.c_str(), ds.width, ds.height, d.z.cols, d.z.rows));
  Require(ps == cv::Size() || ps == nadir.size(), ErrorCode::kInvalidArgument,
          cv::format("%s does not match %s: it registered a %dx%d photo, this one is %dx%d", a.stage1.c_str(),
                     a.nadir.c_str(), ps.width, ps.height, nadir.cols, nadir.rows));
  double res = a.res_m;
  if (res <= 0 && s1.contains("depth") && s1["depth"].contains("res_m") && s1["depth"]["res_m"].is_number())
    res = s1["depth"]["res_m"].get<double>();
  if (res <= 0) res = d.res_m;
  Require(res > 0, ErrorCode::kInvalidArgument,
          a.depth + ": its ground resolution is unknown (no georeference); pass --res METRES");
  const double f = a.focal > 0 ? a.focal : (oblique.cols / 2.0) / std::tan(a.hfov * CV_PI / 360);
  const cv::Matx33d K(f, 0, (oblique.cols - 1) / 2.0, 0, f, (oblique.rows - 1) / 2.0, 0, 0, 1);
  const double read_ms = total.ElapsedMs();

  // stage 2: MVKP trained on the nadir photo, its verified matches lifted
  Timer tm;
  const Model model = TrainNamed(a.nadir, nadir, TrainOptions{});
  const double train_ms = tm.ElapsedMs();
  tm.Restart();
  const MatchResult m = Matcher(model, MatchOptions{}).Match(oblique);
  const double match_ms = tm.ElapsedMs();
  tm.Restart();
  const NadirLifter lifter(d.z, res, nadir_to_depth, lean);
  std::vector<cv::Point3d> X;
  std::vector<cv::Point2d> x;
  std::vector<size_t> from;
  for (size_t i = 0; i < m.matches.size(); ++i) {
    if (!m.matches[i].inlier) continue;
    cv::Point3d w;
    if (lifter.Lift(cv::Point2d(m.matches[i].object), &w)) X.push_back(w), x.emplace_back(m.matches[i].query), from.push_back(i);
  }
  const ViewPose p = EstimateViewPose(X, x, K, a.pose);
  const double pose_ms = tm.ElapsedMs();
  const double z0 = lifter.ground_height();

  if (a.json) {
    Json out;
    out["method"] = "mvkp-pnp";
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
      out["ground_homography"] = Mat(G, 3, 3);  // depth px at the ground height -> oblique px
      out["homography"] = Mat(G * nadir_to_depth, 3, 3);  // nadir px -> oblique px, for the ground plane
    } else {
      out["camera"] = nullptr;
      out["homography"] = nullptr;
    }
    Json ms = Json::array();
    for (size_t k = 0; k < from.size(); ++k) {
      const auto& c = m.matches[from[k]];
      ms.push_back({c.object.x, c.object.y, c.query.x, c.query.y, c.distance, p.ok && p.inlier[k] ? 1 : 0});
    }
    out["matches"] = ms;
    out["keypoints1"] = model.locations.size();
    out["keypoints2"] = m.keypoints;
    out["lifted"] = X.size();
    out["inliers"] = p.inliers;
    out["rms_px"] = p.rms_px;
    out["time_ms"] = {{"read", read_ms}, {"train", train_ms}, {"match", match_ms}, {"pose", pose_ms},
                      {"total", total.ElapsedMs()}};
    std::cout << out.dump() << std::endl;
  } else {
    std::printf("%s -> %s: %s; %s; %.0f ms\n", a.nadir.c_str(), a.oblique.c_str(), p.ok ? "camera found" : "no camera",
                p.reason.c_str(), total.ElapsedMs());
  }
  if (!a.draw.empty()) {
    // the LiDAR's building outlines, at their roof heights, in the view
    cv::Mat img = LoadImageColor(a.oblique);
    if (p.ok) {
      for (const auto& r : SegmentDepth(d.z)) {
        std::vector<cv::Point> poly;
        for (const auto& q : r.contour) {
          float z = -1e9f;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int yy = std::clamp(q.y + dy, 0, d.z.rows - 1), xx = std::clamp(q.x + dx, 0, d.z.cols - 1);
              if (std::isfinite(d.z(yy, xx))) z = std::max(z, d.z(yy, xx));
            }
          if (z < -1e8f) continue;
          const cv::Vec3d v = p.camera * cv::Vec4d(q.x * res, -q.y * res, z, 1);
          if (v[2] > 0) poly.emplace_back(int(std::lround(v[0] / v[2])), int(std::lround(v[1] / v[2])));
        }
        if (poly.size() >= 3) cv::polylines(img, std::vector<std::vector<cv::Point>>{poly}, true, {0, 0, 255}, 2);
      }
    }
    SaveImage(a.draw, img);
  }
  return 0;
}

}  // namespace

void RegisterRegisterView(CLI::App& app, int* code) {
  auto a = std::make_shared<RegisterViewArgs>();
  auto* c = app.add_subcommand(
      "register-view",
      "Stage 2 (issue 22): the camera of an oblique view OBLIQUE of the area of NADIR, through NADIR's "
      "registration to DEPTH (STAGE1 = the output of mvkp register DEPTH NADIR --json). MVKP trained on "
      "NADIR finds OBLIQUE; its matches, lifted to 3-D through stage 1, give the camera by PnP + RANSAC");
  c->add_option("DEPTH", a->depth, "depth raster (as for mvkp register)")->required();
  c->add_option("NADIR", a->nadir, "the nadir photo registered by stage 1")->required();
  c->add_option("STAGE1", a->stage1, "mvkp register DEPTH NADIR --json output")->required();
  c->add_option("OBLIQUE", a->oblique, "the oblique view")->required();
  c->add_option("--focal", a->focal, "focal length of the oblique camera, pixels (default: from --hfov)")
      ->check(CLI::Range(1.0, 1e6));
  c->add_option("--hfov", a->hfov, "horizontal field of view of the oblique camera, degrees")
      ->check(CLI::Range(5.0, 150.0))
      ->capture_default_str();
  c->add_option("--res", a->res_m, "depth raster cell size, metres (default: from STAGE1 or the raster)")
      ->check(CLI::Range(0.01, 100.0));
  c->add_option("--min-inliers", a->pose.min_inliers, "matches the camera must explain")
      ->check(CLI::Range(6, 100000))
      ->capture_default_str();
  c->add_flag("--json", a->json, "print the camera and the correspondences as JSON");
  c->add_option("--draw", a->draw, "write the view with the LiDAR's building outlines reprojected");
  c->callback([a, code] { *code = RunRegisterView(*a); });
}

}  // namespace mvkp::cli
