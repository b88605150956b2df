// mvkp segment depth|optical IMAGE: building regions of one image.
// mvkp register DEPTH OPTICAL: an aerial photo onto LiDAR depth with no
// georeference (thesis ch. 7, stage 1): building regions from both
// (src/mvkp/buildings, src/mvkp/ortho), matched by shape contexts and
// propagated to a global transform (src/mvkp/shapes).
//
// register --json answers in the correspondence JSON (image 1 = the photo,
// image 2 = the depth image; "homography" maps photo pixels to depth pixels,
// null when no registration is found) with the registration's own fields:
// ok, reason, model, regions, region_matches, time_ms per stage.
#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
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
#include "mvkp/aerial/aerial.h"
#include "mvkp/buildings/depth_regions.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/geo/raster.h"
#include "mvkp/ortho/optical_regions.h"
#include "mvkp/ortho/ortho_models.h"
#include "mvkp/shapes/register.h"

namespace mvkp::cli {
namespace {

using Json = nlohmann::json;

// Resident memory from /proc/self/status (VmHWM is the peak; getrusage's
// ru_maxrss would carry the high-water mark of the process that exec'd us).
double StatusMb(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const std::string k = key;
  while (std::getline(f, line))
    if (line.rfind(k, 0) == 0) return std::stod(line.substr(k.size())) / 1024.0;  // kB
  return 0;
}
double PeakRssMb() { return StatusMb("VmHWM:"); }
double RssMb() { return StatusMb("VmRSS:"); }

Json PointsJson(const std::vector<cv::Point>& c) {
  Json a = Json::array();
  for (const auto& p : c) a.push_back({p.x, p.y});
  return a;
}

geo::DepthRaster LoadDepth(const std::string& path, double res_m) {
  geo::DepthReadOptions o;
  if (res_m > 0) o.las.res_m = res_m;
  return geo::ReadDepthRaster(path, o);
}

// Heights as an 8-bit colour image for drawings.
cv::Mat DepthColour(const cv::Mat1f& z) {
  double lo = 0, hi = 1;
  cv::Mat1b valid = (z == z);
  cv::minMaxLoc(z, &lo, &hi, nullptr, nullptr, valid);
  cv::Mat1b g;
  z.convertTo(g, CV_8U, hi > lo ? 255.0 / (hi - lo) : 1.0, hi > lo ? -lo * 255.0 / (hi - lo) : 0.0);
  g.setTo(0, ~valid);
  cv::Mat c;
  cv::applyColorMap(g, c, cv::COLORMAP_VIRIDIS);
  return c;
}

// ----------------------------------------------------------------- segment

// --fbm / --lda: the photo segmentation's models (mvkp ortho-models).
void LoadOrthoModels(const std::string& fbm, const std::string& lda, OpticalSegmentOptions& o) {
  if (!fbm.empty()) o.fbm = LoadFbmModel(fbm);
  if (!lda.empty()) o.lda = LoadRegionLda(lda);
}

struct SegmentArgs {
  std::string kind, image, draw, fbm, lda;
  bool json = false;
  double res_m = 0;
};

int RunSegment(const SegmentArgs& a) {
  try {
    Timer t;
    Json out = {{"image", a.image}, {"kind", a.kind}};
    Json regions = Json::array();
    cv::Mat drawing;
    if (a.kind == "depth") {
      const geo::DepthRaster d = LoadDepth(a.image, a.res_m);
      const double read_ms = t.ElapsedMs();
      Timer ts;
      const std::vector<BuildingRegion> r = SegmentDepth(d.z);
      out["time_ms"] = {{"read", read_ms}, {"segment", ts.ElapsedMs()}};
      out["size"] = {d.z.cols, d.z.rows};
      out["res_m"] = d.res_m;
      for (const auto& x : r)
        regions.push_back({{"area_px", x.area}, {"height_m", x.height}, {"contour", PointsJson(x.contour)}});
      if (!a.draw.empty()) drawing = DrawRegions(d.z, r);
    } else {
      const geo::OpticalImage img = geo::ReadOpticalImage(a.image);
      const double read_ms = t.ElapsedMs();
      Timer ts;
      OpticalSegmentOptions oo;
      LoadOrthoModels(a.fbm, a.lda, oo);
      const std::vector<PhotoRegion> r = SegmentOptical(img.bgr, oo);
      out["time_ms"] = {{"read", read_ms}, {"segment", ts.ElapsedMs()}};
      out["size"] = {img.bgr.cols, img.bgr.rows};
      for (const auto& x : r)
        regions.push_back({{"area_px", x.area}, {"confidence", x.confidence}, {"contour", PointsJson(x.contour)}});
      if (!a.draw.empty()) drawing = DrawPhotoRegions(img.bgr, r);
    }
    out["regions"] = regions;
    if (!a.draw.empty()) SaveImage(a.draw, drawing);
    if (a.json) std::cout << out.dump() << std::endl;
    else std::printf("%s: %zu building regions (%s)\n", a.image.c_str(), regions.size(), a.kind.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvkp segment: %s\n", e.what());
    return 1;
  }
}

// ---------------------------------------------------------------- register

struct RegisterArgs {
  std::string depth, optical, draw, model = "auto", fbm, lda, method = "auto";
  double min_confidence = OutlineSearchOptions{}.min_confidence;
  bool json = false;
  double res_m = 0;
  int photo_max_side = 1200;
  int photo_min_side = AerialOptions{}.photo_min_side;
  double photo_max_upscale = AerialOptions{}.photo_max_upscale;
  bool shadows = AerialOptions{}.shadows.enabled;
  bool shadow_fallback = AerialOptions{}.shadow_fallback;
  bool cast_shadow_fallback = AerialOptions{}.cast_shadow_fallback;
  double cast_shadow_confirm_margin = AerialOptions{}.cast_shadow_confirm_margin;
  int outline_roof_veto_regions = AerialOptions{}.outline_roof_veto_regions;
  int outline_max_regions = AerialOptions{}.auto_outline_max_regions;
  int outline_max_side = AerialOptions{}.outline_max_side;
  bool no_outline_objects = false;
  double outline_object_weight = OutlineSearchOptions{}.object_weight;
  double outline_completeness = OutlineSearchOptions{}.completeness_power;
  double outline_min_completeness = OutlineSearchOptions{}.min_completeness;
  double outline_relocate_confidence = AerialOptions{}.outline_relocate_confidence;
  RegistrationOptions opt;
  EdgeEvidenceOptions edge;
};

// Photo (left, scaled to the depth image's height) and depth (right), their
// regions, the matched pairs joined, and when registered the photo's regions
// projected onto the depth image (as thesis Figs 7.28-7.29).
cv::Mat DrawRegistration(const cv::Mat& photo, const cv::Mat1f& depth, const std::vector<Contour>& pr,
                         const std::vector<Contour>& dr, const Registration& reg) {
  const double s = double(depth.rows) / std::max(1, photo.rows);
  cv::Mat left;
  cv::resize(photo, left, cv::Size(std::max(1, int(std::lround(photo.cols * s))), depth.rows), 0, 0, cv::INTER_AREA);
  cv::Mat right = DepthColour(depth);
  cv::Mat canvas(depth.rows, left.cols + right.cols, CV_8UC3);
  left.copyTo(canvas(cv::Rect(0, 0, left.cols, left.rows)));
  right.copyTo(canvas(cv::Rect(left.cols, 0, right.cols, right.rows)));
  const cv::Point2f off(float(left.cols), 0.f);
  auto poly = [&](const Contour& c, double scale, cv::Point2f shift, const cv::Scalar& col, int w) {
    std::vector<cv::Point> p;
    for (const auto& q : c) p.emplace_back(cv::Point(int(std::lround(q.x * scale + shift.x)), int(std::lround(q.y * scale + shift.y))));
    if (p.size() >= 2) cv::polylines(canvas, p, true, col, w, cv::LINE_AA);
  };
  for (const auto& c : pr) poly(c, s, {0, 0}, {255, 200, 0}, 1);
  for (const auto& c : dr) poly(c, 1.0, off, {255, 255, 255}, 1);
  auto centroid = [](const Contour& c) {
    cv::Point2f m(0, 0);
    for (const auto& p : c) m += p;
    return c.empty() ? m : m * (1.f / float(c.size()));
  };
  for (const auto& m : reg.region_matches) {
    if (m.a < 0 || m.b < 0 || m.a >= int(pr.size()) || m.b >= int(dr.size())) continue;
    const cv::Point2f a = centroid(pr[std::size_t(m.a)]) * float(s), b = centroid(dr[std::size_t(m.b)]) + off;
    cv::line(canvas, a, b, {0, 220, 0}, 1, cv::LINE_AA);
  }
  if (reg.ok)
    for (const auto& c : pr) poly(TransformPoints(reg.photo_to_depth, c), 1.0, off, {0, 0, 255}, 2);
  const std::string text = reg.ok ? "registered (" + reg.model + ")" : reg.reason;
  cv::putText(canvas, text.substr(0, 80), {8, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {0, 0, 0}, 3, cv::LINE_AA);
  cv::putText(canvas, text.substr(0, 80), {8, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6, {255, 255, 255}, 1, cv::LINE_AA);
  return canvas;
}

// The registration as `mvkp register --json` prints it (and the drawing).
// glibc raises its mmap threshold each time a large block is freed, so
// later image-sized buffers come from the heap, whose freed pages stay
// resident: the registration's passes over one photo ratcheted its peak RSS
// by 10-13 MB (issue 21, seed 125: 108-112 MB -> 95-104 MB). A fixed
// threshold keeps every buffer of 1 MB or more (a working photo's 8-bit
// maps; 4 MB until the depth's shadows added a pass that makes several)
// in its own mapping, returned to the system when freed (seed 122 suburb
// 34: 99.96 -> 95.5 MB); times within the runs' noise.
void ReturnLargeBuffers() {
  static const bool once = [] { return ::mallopt(M_MMAP_THRESHOLD, 1 << 20) == 1; }();
  (void)once;
}

Json RegisterCompute(RegisterArgs& a) {
  ReturnLargeBuffers();
  {
    if (a.model == "similarity") a.opt.model = RegistrationOptions::Model::kSimilarity;
    else if (a.model == "affine") a.opt.model = RegistrationOptions::Model::kAffine;
    else if (a.model == "perspective") a.opt.model = RegistrationOptions::Model::kPerspective;
    else a.opt.model = RegistrationOptions::Model::kAuto;
    const double start_rss_mb = RssMb();
    Timer total;
    geo::DepthRaster d = LoadDepth(a.depth, a.res_m);
    geo::OpticalImage img = geo::ReadOpticalImage(a.optical);
    const double read_ms = total.ElapsedMs();
    AerialOptions ao;
    ao.photo_max_side = a.photo_max_side;
    ao.photo_min_side = a.photo_min_side;
    ao.photo_max_upscale = a.photo_max_upscale;
    ao.shadows.enabled = a.shadows;
    ao.shadow_fallback = a.shadow_fallback;
    ao.cast_shadow_fallback = a.cast_shadow_fallback;
    ao.cast_shadow_confirm_margin = a.cast_shadow_confirm_margin;
    ao.outline_roof_veto_regions = a.outline_roof_veto_regions;
    ao.registration = a.opt;
    ao.edge = a.edge;
    ao.image_check = a.edge.min_contrast > 0;
    if (!ao.image_check) ao.edge.min_contrast = EdgeEvidenceOptions{}.min_contrast;
    LoadOrthoModels(a.fbm, a.lda, ao.optical);
    ao.method = a.method == "regions"    ? AerialOptions::Method::kRegions
                : a.method == "outlines" ? AerialOptions::Method::kOutlines
                                         : AerialOptions::Method::kAuto;
    ao.outline.min_confidence = a.min_confidence;
    ao.auto_outline_max_regions = a.outline_max_regions;
    ao.outline_max_side = a.outline_max_side;
    ao.outline_objects = !a.no_outline_objects;
    ao.outline.object_weight = a.outline_object_weight;
    ao.outline.completeness_power = a.outline_completeness;
    ao.outline.min_completeness = a.outline_min_completeness;
    ao.outline_relocate_confidence = a.outline_relocate_confidence;
    ao.photo_res_m = img.res_m;
    ao.depth_res_m = d.res_m;
    const cv::Size photo_size = img.bgr.size(), depth_size = d.z.size();
    // Without a drawing, the pixels are not needed after the pipeline used them.
    const bool keep = !a.draw.empty();
    const AerialRegistration ar =
        RegisterAerial(keep ? d.z : std::move(d.z), keep ? img.bgr : std::move(img.bgr), ao);
    const Registration& reg = ar.registration;
    const std::vector<Contour>& pcont = ar.photo_regions;
    const std::vector<Contour>& dcont = ar.depth_regions;
    const double depth_ms = ar.segment_depth_ms, photo_ms = ar.segment_photo_ms;
    const double total_ms = total.ElapsedMs();

    Json out;
    out["method"] = "mvkp-register";
    out["ok"] = reg.ok;
    out["reason"] = reg.reason;
    out["model"] = reg.ok ? Json(reg.model) : Json(nullptr);
    // which method answered ("method" is the tool's name in the correspondence JSON)
    out["registration_method"] = reg.ok ? Json(ar.method) : Json(nullptr);
    out["confidence"] = reg.ok ? ar.confidence : 0.0;
    // the largest mean gap (depth px) to an equally good pose found by the
    // ambiguity check (RegistrationOptions::ambiguity_px); 0 when it did not run
    out["ambiguity_px"] = reg.ambiguity_px;
    // how far the relocation moved the answer (EdgeEvidence::Relocate; mean
    // over the outlines in view, depth px); 0 when it kept it
    out["relocated_px"] = reg.ok ? reg.relocated_px : 0.0;
    // the photo's lean (conventional orthophoto): roofs show lean * height
    // away from their footprints; the homography maps the ground
    if (reg.ok) {
      out["lean_depth_px_per_m"] = {reg.lean_px_per_m.x, reg.lean_px_per_m.y};
      out["lean_m_per_m"] = d.res_m > 0 ? Json{reg.lean_px_per_m.x * d.res_m, reg.lean_px_per_m.y * d.res_m} : Json(nullptr);
    } else {
      out["lean_depth_px_per_m"] = nullptr, out["lean_m_per_m"] = nullptr;
    }
    // cast-shadow compensation (ortho/shadows.h): the step found, in log
    // B, G, R, the fraction of the working photo relit, and whether the
    // answer is the shadow fallback's (a second pass on the relit photo)
    out["shadows"] = {{"applied", ar.shadows.applied}, {"fallback_answer", ar.shadow_fallback_used},
                      {"log_step_bgr", ar.shadows.applied ? Json{ar.shadows.log_step[0], ar.shadows.log_step[1],
                                                                 ar.shadows.log_step[2]}
                                                          : Json(nullptr)},
                      {"fraction", ar.shadows.fraction}, {"votes", ar.shadows.votes}, {"time_ms", ar.shadows.ms}};
    // the depth's shadows (aerial/cast_shadows.h), when that fallback ran:
    // the sun fitted at the outline search's best pose, whether the photo
    // was relit by it, and whether the answer is that pass's
    if (ar.cast_shadows.ms > 0 || ar.cast_shadow_fallback_used) {
      const CastShadowFit& cf = ar.cast_shadows;
      out["cast_shadows"] = {{"found", cf.found},
                             {"applied", cf.applied},
                             {"fallback_answer", ar.cast_shadow_fallback_used},
                             {"reason", cf.reason},
                             {"buildings", cf.buildings},
                             {"azimuth_deg", cf.azimuth_deg},
                             {"length_depth_px_per_m", cf.length_px_per_m},
                             {"contrast", cf.contrast},
                             {"margin", cf.margin},
                             {"log_step_bgr", Json{cf.log_step[0], cf.log_step[1], cf.log_step[2]}},
                             {"fraction", cf.fraction},
                             {"time_ms", cf.ms}};
    }
    if (ar.outline_search_ran) {
      const OutlineSearchResult& os = ar.outline;
      out["outline_search"] = {{"ok", os.ok},           {"confidence", os.confidence}, {"score", os.score},
                               {"runner_up", os.runner_up}, {"coverage", os.coverage}, {"completeness", os.completeness}, {"poses", os.poses},
                               {"edge_contrast", os.edge.enough ? Json(os.edge.contrast) : Json(nullptr)},
                               {"ambiguity_px", os.ambiguity_px},
                               {"time_ms", os.ms},      {"reason", os.reason}};
      Json h = Json::array();  // its best pose, accepted or not (for analysis)
      for (int r = 0; r < 3; ++r) h.push_back({os.photo_to_depth(r, 0), os.photo_to_depth(r, 1), os.photo_to_depth(r, 2)});
      out["outline_search"]["best_pose"] = h;
    } else {
      out["outline_search"] = nullptr;
    }
    if (reg.ok) {
      Json h = Json::array();
      for (int r = 0; r < 3; ++r) h.push_back({reg.photo_to_depth(r, 0), reg.photo_to_depth(r, 1), reg.photo_to_depth(r, 2)});
      out["homography"] = h;
    } else {
      out["homography"] = nullptr;
    }
    out["keypoints1"] = pcont.size();
    out["keypoints2"] = dcont.size();
    out["regions"] = {{"photo", pcont.size()}, {"depth", dcont.size()}};
    // how many times the working photo's size its regions were segmented at
    // (> 1: a coarse photo, segmented again upscaled; aerial.h photo_min_side)
    out["photo_segmentation_upscale"] = ar.photo_upscale;
    Json matches = Json::array();
    for (const auto& [p, q] : reg.correspondences) matches.push_back({p.x, p.y, q.x, q.y, 0.0, 1});
    out["matches"] = matches;
    Json rm = Json::array();
    for (const auto& m : reg.region_matches)
      rm.push_back({{"photo", m.a}, {"depth", m.b}, {"cost", m.cost}, {"cost_ratio", m.cost_ratio}});
    out["region_matches"] = rm;
    out["rms_px"] = reg.rms_px;
    if (reg.edge.enough)
      out["edge"] = {{"points", reg.edge.points},
                     {"contrast", reg.edge.contrast},
                     {"regions", reg.edge.regions},
                     {"regions_on_edges", reg.edge.regions_on_edges},
                     {"roof_regions", reg.edge.roof_regions},
                     {"roof_contrast", reg.edge.roof_regions > 0 ? Json(reg.edge.roof_contrast) : Json(nullptr)}};
    else out["edge"] = nullptr;
    out["hypotheses"] = reg.hypotheses;
    out["depth"] = {{"size", {depth_size.width, depth_size.height}}, {"res_m", d.res_m}};
    out["photo"] = {{"size", {photo_size.width, photo_size.height}}};
    out["time_ms"] = {{"read", read_ms},          {"segment_depth", depth_ms}, {"segment_photo", photo_ms},
                      {"match", reg.match_ms},    {"propagate", reg.propagate_ms},
                      {"outline_search", ar.outline_search_ms},
                      {"query", total_ms - read_ms}, {"total", total_ms}};
    out["peak_rss_mb"] = PeakRssMb();
    // What the registration itself needed: the peak over the resident size at
    // start (shared libraries, mostly OpenCV and GDAL's, ~75 MB of it).
    out["peak_rss_above_start_mb"] = PeakRssMb() - start_rss_mb;
    if (!a.draw.empty()) SaveImage(a.draw, DrawRegistration(img.bgr, d.z, pcont, dcont, reg));
    return out;
  }
}

int RunRegister(RegisterArgs& a) {
  try {
    const Json out = RegisterCompute(a);
    if (a.json) {
      std::cout << out.dump() << std::endl;
    } else if (out["ok"].get<bool>()) {
      std::printf("registered by %s (%s, confidence %.2f): %zu region pairs, RMS %.2f px, %.0f ms\n",
                  out["registration_method"].get<std::string>().c_str(), out["model"].get<std::string>().c_str(),
                  out["confidence"].get<double>(), out["region_matches"].size(), out["rms_px"].get<double>(),
                  out["time_ms"]["total"].get<double>());
    } else {
      std::printf("%s (%zu photo / %zu depth regions, %.0f ms)\n", out["reason"].get<std::string>().c_str(),
                  out["regions"]["photo"].get<size_t>(), out["regions"]["depth"].get<size_t>(),
                  out["time_ms"]["total"].get<double>());
    }
    return 0;  // "no registration found" is an answer, not an error
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvkp register: %s\n", e.what());
    return 1;
  }
}

}  // namespace

nlohmann::json RegisterNadir(const std::string& depth, const std::string& nadir, double res_m) {
  RegisterArgs a;  // mvkp register's defaults
  a.depth = depth, a.optical = nadir, a.res_m = res_m;
  return RegisterCompute(a);
}

void RegisterSegment(CLI::App& app, int* code) {
  auto a = std::make_shared<SegmentArgs>();
  auto* c = app.add_subcommand("segment", "Building regions of a depth image (LiDAR) or an aerial photo");
  c->add_option("KIND", a->kind, "depth | optical")->required()->check(CLI::IsMember({"depth", "optical"}));
  c->add_option("IMAGE", a->image, "GeoTIFF DSM/nDSM or LAS (depth), or a photo (optical)")->required();
  c->add_option("--draw", a->draw, "write the regions over the image");
  c->add_flag("--json", a->json, "regions as JSON (contours in pixels)");
  c->add_option("--res", a->res_m, "LAS input: raster cell size, metres (default 0.5)")->check(CLI::Range(0.01, 100.0));
  c->add_option("--fbm", a->fbm, "optical: fBm model file (mvkp ortho-models fit-fbm; default: fitted on the photo)");
  c->add_option("--lda", a->lda, "optical: region LDA file (mvkp ortho-models train-lda; default: built in)");
  c->callback([a, code] { *code = RunSegment(*a); });
}

void RegisterRegister(CLI::App& app, int* code) {
  auto a = std::make_shared<RegisterArgs>();
  auto* c = app.add_subcommand("register", "Register an aerial photo onto LiDAR depth by building shapes (no georeference needed)");
  c->add_option("DEPTH", a->depth, "GeoTIFF DSM/nDSM or uncompressed LAS")->required();
  c->add_option("OPTICAL", a->optical, "the aerial photo")->required();
  c->add_option("--res", a->res_m, "LAS input: raster cell size, metres (default 0.5)")->check(CLI::Range(0.01, 100.0));
  c->add_flag("--json", a->json, "the correspondence JSON with the registration's fields");
  c->add_option("--draw", a->draw, "write regions and matches (photo left, depth right)");
  c->add_option("--model", a->model, "global transform: auto | similarity | affine | perspective")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "similarity", "affine", "perspective"}));
  c->add_option("--method", a->method,
                 "regions (shape contexts), outlines (global search of the depth outlines over the photo edges), "
                 "or auto (regions, then outlines when they find nothing)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "regions", "outlines"}));
  c->add_option("--min-confidence", a->min_confidence, "outline search: confidence needed to accept")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  c->add_option("--outline-max-regions", a->outline_max_regions,
                "auto: run the outline search only on depths with at most this many building regions (0: any)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000000));
  c->add_option("--outline-max-side", a->outline_max_side,
                "outline search: the side of the photo copy it searches, px (0: the working photo; else >= 64)")
      ->capture_default_str()
      ->check(CLI::Range(0, 20000));
  c->add_flag("--no-outline-objects", a->no_outline_objects,
              "outline search: score the building outlines only, not those of trees, hedges and sheds");
  c->add_option("--outline-object-weight", a->outline_object_weight,
                "outline search: the weight of a tree's, hedge's or shed's outline sample against a building's")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  c->add_option("--outline-completeness", a->outline_completeness,
                "outline search: a pose's score is weighted by the share of its building outlines' arcs on edges, "
                "to this power (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 4.0));
  c->add_option("--outline-min-completeness", a->outline_min_completeness,
                "outline search: an answer needs this share of its building outlines' arcs in view on edges (a pose "
                "on other ground lays parts of several outlines on a similar street grid; 0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  c->add_option("--outline-relocate-confidence", a->outline_relocate_confidence,
                "outline search: its refused best pose is relocated onto the edges and judged again when its "
                "confidence reaches this (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  c->add_flag("--principal-directions", a->opt.use_principal_directions,
              "try rotations from the scenes' principal directions first (thesis 7.2.4; falls back)");
  c->add_option("--seed", a->opt.seed, "hypothesis order seed")->capture_default_str();
  c->add_option("--min-regions", a->opt.min_regions, "consistent region pairs needed to accept")
      ->capture_default_str()
      ->check(CLI::Range(2, 1000));
  c->add_option("--max-rms", a->opt.max_rms_px, "final RMS contour distance (depth px) needed to accept")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0));
  c->add_option("--ambiguity-px", a->opt.ambiguity_px,
                "refuse a perspective answer when a pose refined from a perturbation of it scores as well and "
                "lies this far away on average over the outlines in view (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  c->add_option("--max-anisotropy", a->opt.max_anisotropy,
                "refuse a transform that stretches the photo along one axis this many times more than along "
                "the other, at its centre (nadir photos: square pixels; 0: off)")
      ->capture_default_str()
      ->check(CLI::Number);
  c->add_option("--min-edge-contrast", a->edge.min_contrast,
                "image check: depth outlines must lie on photo edges this much more than beside them (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  c->add_option("--roof-veto", a->edge.roof_veto,
                "image check: refuse an answer whose outlines in view set roofs apart from the ground by less "
                "than this (median colour contrast, inside vs around) unless its edge contrast reaches 2.2 (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  c->add_option("--roof-veto-outlines", a->edge.min_roof_veto_regions,
                "image check: the roof veto decides over at least this many outlines in view (roofs admit over "
                "at least 4)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  c->add_option("--roof-accept", a->edge.roof_accept,
                "image check: a roof contrast this clear admits an edge contrast down to "
                "--min-edge-contrast-with-roofs (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  c->add_option("--min-edge-contrast-with-roofs", a->edge.min_contrast_with_roofs,
                "image check: the edge contrast a clear roof contrast admits")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 100.0));
  c->add_flag("!--accept-shapes-alone", a->opt.require_image_evidence,
              "also accept on region shapes alone when the image check fails (leaning orthophotos; "
              "can accept look-alike sets far off)");
  c->add_flag("!--no-edge-refine", a->opt.edge_refine, "keep the shape-fitted transform (no snapping onto photo edges)");
  c->add_flag_callback("--no-lean", [a] { a->edge.max_lean_px_per_m = 0; },
                       "do not estimate the photo's lean (roofs displaced by height x lean in a conventional "
                       "orthophoto); the answer then maps the mean roof");
  c->add_option("--relocate-rounds", a->edge.relocate_rounds,
                "image check: relocations of an accepted answer at most (its error measured cell by cell over "
                "the photo, a homography fitted to it; kept when the outlines lie on edges >= 5 % better; 0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10));
  c->add_option("--relocate-lean-gain", a->edge.relocate_lean_gain,
                "image check: an accepted answer's lean jump (other leans held while the transform is refined) "
                "is kept when the outlines lie on edges this much better (0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  c->add_option("--relocate-lean-roof-gain", a->edge.relocate_lean_roof_gain,
                "image check: the lean jump is also kept at a 2 % edge gain when the roofs inside the outlines "
                "stand apart this share more (0: the edge gain alone decides)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  c->add_option("--lean-min-roof-ratio", a->opt.lean_min_roof_ratio,
                "region route: the answer refined with the photo's lean replaces the lean-free one only when "
                "the roofs inside its outlines stand apart at least this share as much (0: the edges alone decide)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 2.0));
  c->add_flag("!--no-joint-lean", a->opt.joint_lean_fit,
              "estimate the lean from the lean-free fit only (no second start from the region pairs refitted "
              "with the lean)");
  c->add_flag("!--no-single-pair", a->opt.single_pair_route,
              "no single-pair route (one region pair's transform judged by the image check alone, when no "
              "consistent set of region pairs passes)");
  c->add_option("--fbm", a->fbm, "fBm model file (mvkp ortho-models fit-fbm; default: fitted on the photo)");
  c->add_option("--lda", a->lda, "region LDA file (mvkp ortho-models train-lda; default: built in)");
  c->add_option("--photo-max-side", a->photo_max_side, "segment larger photos downscaled to this side (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  c->add_option("--photo-min-side", a->photo_min_side,
                "coarse photos: when the working size finds no registration, try the photo segmented upscaled to this side, by at most --photo-max-upscale (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  c->add_option("--photo-max-upscale", a->photo_max_upscale, "the largest upscaling of --photo-min-side")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 8.0));
  c->add_flag("--shadow-compensation", a->shadows,
              "relight cast shadows first (ortho/shadows.h; off by default: as the first pass it loses as many "
              "answers as it gains, docs/aerial.md)");
  c->add_flag("!--no-shadow-fallback", a->shadow_fallback,
              "no second pass on the photo with its cast shadows relit when the photo as it is gives no "
              "registration (the second pass answers only by region shapes)");
  c->add_flag("!--no-cast-shadow-fallback", a->cast_shadow_fallback,
              "no last pass on the photo with the shadows the depth casts at the outline search's best pose "
              "relit (aerial/cast_shadows.h; answers only by region shapes)");
  c->add_option("--cast-shadow-confirm-margin", a->cast_shadow_confirm_margin,
                 "when the pass with the depth's shadows relit does not answer either, the pose whose shadows "
                 "stood out by this margin answers if its outlines and roofs pass the outline search's checks "
                 "on the relit photo (--method auto only; 0: off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  c->add_option("--outline-roof-veto-regions", a->outline_roof_veto_regions,
                 "an outline-search answer whose roofs, scored over at least this many outlines, do not stand "
                 "apart (--roof-veto) is refused however clear its edges (0: the region routes' rule)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  c->callback([a, code] { *code = RunRegister(*a); });
}

void RegisterOrthoModels(CLI::App& app, int* code) {
  auto* c = app.add_subcommand("ortho-models", "Fit the photo segmentation's models (fBm, region LDA) for a dataset");
  c->require_subcommand(1);
  struct FbmArgs {
    std::vector<std::string> pairs;
    std::string out;
    int window = 7;
  };
  auto f = std::make_shared<FbmArgs>();
  auto* fc = c->add_subcommand("fit-fbm", "Least-squares fBm fit on the non-building areas of photos (thesis 7.2.2)");
  fc->add_option("PHOTO=MASK", f->pairs, "photo and mask (non-zero: not a building), same size")->required();
  fc->add_option("-o", f->out, "model file to write (JSON)")->required();
  fc->add_option("--window", f->window, "fractal-error window side (odd)")->capture_default_str()->check(CLI::Range(3, 31));
  fc->callback([f, code] {
    try {
      std::vector<cv::Mat> images, masks;
      for (const auto& p : f->pairs) {
        const auto eq = p.find('=');
        Require(eq != std::string::npos && eq > 0 && eq + 1 < p.size(), ErrorCode::kInvalidArgument,
                "'" + p + "': expected PHOTO=MASK");
        images.push_back(geo::ReadOpticalImage(p.substr(0, eq)).bgr);
        masks.push_back(LoadImageGray(p.substr(eq + 1)));
        Require(masks.back().size() == images.back().size(), ErrorCode::kInvalidArgument,
                p.substr(eq + 1) + ": mask size differs from its photo's");
      }
      const FbmModel m = FitFbm(images, masks, f->window);
      SaveFbmModel(f->out, m);
      std::cout << Json{{"model", "fbm"}, {"file", f->out}, {"k", m.k}, {"H", m.H}, {"ofe", m.ofe}, {"window", m.window}}.dump()
                << std::endl;
      *code = 0;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mvkp ortho-models fit-fbm: %s\n", e.what());
      *code = 1;
    }
  });
  struct LdaArgs {
    std::string out;
    unsigned seed = 7;
  };
  auto l = std::make_shared<LdaArgs>();
  auto* lc = c->add_subcommand("train-lda", "Train the region-regulation LDA on generated building outlines vs blobs");
  lc->add_option("-o", l->out, "model file to write (JSON)")->required();
  lc->add_option("--seed", l->seed, "seed of the generated training outlines")->capture_default_str();
  lc->callback([l, code] {
    try {
      std::vector<cv::Vec2d> pnr;
      std::vector<int> labels;
      DefaultRegionLdaTrainingSet(&pnr, &labels, l->seed);
      const RegionLda m = TrainRegionLda(pnr, labels);
      SaveRegionLda(l->out, m);
      std::cout << Json{{"model", "lda"}, {"file", l->out}, {"samples", pnr.size()}, {"b", m.b}}.dump() << std::endl;
      *code = 0;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mvkp ortho-models train-lda: %s\n", e.what());
      *code = 1;
    }
  });
}

}  // namespace mvkp::cli
