// mvkp_ortho_eval: roof finding of the optical segmentation (SegmentOptical,
// thesis §7.2.2) on generated cities (issue 8).
//
// Per seed: MakeCity(CityOptions{}, seed), the photo downscaled to
// --max-side (as `mvkp register` does, INTER_AREA; the per-pixel building ids
// with INTER_NEAREST), SegmentOptical single-threaded. Reported per seed and
// overall:
//   roofs found   buildings inside the depth raster with >= --min-pixels
//                 visible photo pixels that some region overlaps with IoU >= 0.5
//   false         regions with less than half of their pixels on buildings
//                 (any building, inside the depth raster or not)
//   on roads      regions with at least half of their pixels on a road or
//                 sidewalk (City::photo_road_mask)
//   ms            SegmentOptical wall time per photo (one thread)
//
//   mvkp_ortho_eval [--seeds 1000 1039] [--max-side 1200] [--draw DIR] [--maps DIR]
//                   [--set NAME=VALUE ...] [--json OUT] [-v]
// --set overrides a numeric/boolean field of OpticalSegmentOptions (tuning);
// -v lists the missed buildings. Tune on seeds 1000-1039, report 2000-2039.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/core/timer.h"
#include "mvkp/ortho/optical_regions.h"

using namespace mvkp;

namespace {

struct SeedResult {
  std::uint64_t seed = 0;
  cv::Size size;
  double scale = 0;
  int roofs = 0, found = 0, regions = 0, false_regions = 0, road_regions = 0;
  double ms = 0;
};

// --set NAME=VALUE: the numeric and boolean fields of OpticalSegmentOptions.
bool SetOption(OpticalSegmentOptions* o, const std::string& n, double v) {
#define MVKP_F(name) \
  if (n == #name) { \
    o->name = static_cast<decltype(o->name)>(v); \
    return true; \
  }
  MVKP_F(pre_blur_sigma)
  MVKP_F(thin_suppress)
  MVKP_F(use_vegetation)
  MVKP_F(veg_green_margin)
  MVKP_F(veg_exg)
  MVKP_F(veg_exg_rel)
  MVKP_F(use_shadow)
  MVKP_F(shadow_intensity)
  MVKP_F(shadow_channel)
  MVKP_F(canny_low)
  MVKP_F(canny_high)
  MVKP_F(split_edges)
  MVKP_F(edge_probe)
  MVKP_F(hue_similar)
  MVKP_F(sat_min_for_hue)
  MVKP_F(gray_similar)
  MVKP_F(selective_smoothing)
  MVKP_F(barrier_dilate)
  MVKP_F(seed_cell)
  MVKP_F(use_fractal)
  MVKP_F(ofe_ratio)
  MVKP_F(range_tolerance)
  MVKP_F(range_tolerance_strict)
  MVKP_F(range_soft_max)
  MVKP_F(range_len)
  MVKP_F(max_chroma_step)
  MVKP_F(color_margin)
  MVKP_F(irep_penalty)
  MVKP_F(min_area)
  MVKP_F(max_area_fraction)
  MVKP_F(max_upp)
  MVKP_F(upp_scale)
  MVKP_F(merge)
  MVKP_F(merge_gap)
  MVKP_F(merge_min_contact)
  MVKP_F(merge_max_true_edge)
  MVKP_F(merge_max_chroma)
  MVKP_F(regulate)
  MVKP_F(lda_margin)
  MVKP_F(lda_border_relax)
  MVKP_F(max_elongation)
  MVKP_F(min_rectilinear)
  MVKP_F(min_shadow_ring)
  MVKP_F(shadow_ring_ratio)
  MVKP_F(max_elongation_unshaded)
  MVKP_F(shadow_ring_evidence)
  MVKP_F(min_solidity)
  MVKP_F(contour_dilate)
#undef MVKP_F
  return false;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Roof finding of SegmentOptical on generated cities (issue 8)"};
  std::vector<std::uint64_t> seeds{1000, 1039};
  int max_side = 1200, min_pixels = 200;
  std::string draw_dir, json_path;
  bool verbose = false;
  std::vector<std::string> sets;
  std::string maps_dir;
  app.add_option("--seeds", seeds, "first and last seed (inclusive)")->expected(2)->capture_default_str();
  app.add_option("--max-side", max_side, "segment the photo downscaled to this longest side (0: never)")
      ->capture_default_str();
  app.add_option("--min-pixels", min_pixels, "count buildings with at least this many visible photo pixels")
      ->capture_default_str();
  app.add_option("--draw", draw_dir, "write DIR/seed_N.png (regions: green found roof, red false, blue other)");
  app.add_option("--json", json_path, "write per-seed and overall results");
  app.add_flag("-v,--verbose", verbose, "print missed buildings");
  app.add_option("--set", sets, "override an option of OpticalSegmentOptions: NAME=VALUE (numeric fields)");
  app.add_option("--maps", maps_dir, "write DIR/maps_N.png (DrawOpticalMaps)");
  CLI11_PARSE(app, argc, argv);

  OpticalSegmentOptions opt;
  for (const std::string& s : sets) {
    const size_t eq = s.find('=');
    if (eq == std::string::npos || !SetOption(&opt, s.substr(0, eq), std::stod(s.substr(eq + 1)))) {
      std::fprintf(stderr, "--set %s: unknown option\n", s.c_str());
      return 2;
    }
  }
  SegmentOptical(cv::Mat3b(64, 64, cv::Vec3b(100, 100, 100)), opt);  // warm-up (LDA training)
  const int threads = cv::getNumThreads();
  std::vector<SeedResult> results;
  std::printf("%6s %10s %6s %8s %8s %8s %8s %8s %8s\n", "seed", "size", "scale", "roofs", "found", "regions", "false",
              "roads", "ms");
  for (std::uint64_t seed = seeds[0]; seed <= seeds[1]; ++seed) {
    const CityOptions co;
    const City city = MakeCity(co, seed);
    const cv::Mat1b& road_full = city.photo_road_mask;
    cv::Mat3b photo = city.photo;
    cv::Mat1i ids = city.photo_building_id;
    cv::Mat1b road = road_full;
    if (max_side > 0 && std::max(photo.cols, photo.rows) > max_side) {
      const double f = double(max_side) / std::max(photo.cols, photo.rows);
      cv::resize(city.photo, photo, cv::Size(), f, f, cv::INTER_AREA);
      cv::resize(city.photo_building_id, ids, photo.size(), 0, 0, cv::INTER_NEAREST);
      cv::resize(road_full, road, photo.size(), 0, 0, cv::INTER_NEAREST);
    }
    SeedResult res;
    res.seed = seed;
    res.size = photo.size();
    res.scale = city.scale;
    cv::setNumThreads(1);
    Timer timer;
    const std::vector<PhotoRegion> regions = SegmentOptical(photo, opt);
    res.ms = timer.ElapsedMs();
    cv::setNumThreads(threads);

    const int nb = static_cast<int>(city.footprints.size());
    std::vector<int> visible(nb, 0);
    for (int y = 0; y < ids.rows; ++y)
      for (int x = 0; x < ids.cols; ++x)
        if (ids(y, x) >= 0) ++visible[size_t(ids(y, x))];

    // Region masks -> per-building intersections.
    std::vector<double> best_iou(nb, 0);
    std::vector<int> kind;  // 0 other, 1 found roof, 2 false
    for (const PhotoRegion& r : regions) {
      cv::Mat1b mk(photo.size(), 0);
      cv::fillPoly(mk, std::vector<std::vector<cv::Point>>{r.contour}, 255);
      const cv::Rect bb = r.bbox & cv::Rect(0, 0, mk.cols, mk.rows);
      std::vector<int> inter(nb, 0);
      int area = 0, on_b = 0, on_road = 0;
      for (int y = bb.y; y < bb.br().y; ++y)
        for (int x = bb.x; x < bb.br().x; ++x) {
          if (!mk(y, x)) continue;
          ++area;
          const int id = ids(y, x);
          if (id != -1) ++on_b;
          if (id >= 0) ++inter[size_t(id)];
          if (road(y, x)) ++on_road;
        }
      bool hit = false;
      for (int b = 0; b < nb; ++b) {
        if (!inter[size_t(b)]) continue;
        const double iou = double(inter[size_t(b)]) / (area + visible[size_t(b)] - inter[size_t(b)]);
        best_iou[size_t(b)] = std::max(best_iou[size_t(b)], iou);
        hit |= iou >= 0.5 && visible[size_t(b)] >= min_pixels;
      }
      const bool is_false = on_b < 0.5 * area;
      res.false_regions += is_false;
      res.road_regions += on_road >= 0.5 * area;
      kind.push_back(hit ? 1 : is_false ? 2 : 0);
    }
    res.regions = static_cast<int>(regions.size());
    for (int b = 0; b < nb; ++b) {
      if (visible[size_t(b)] < min_pixels) continue;
      ++res.roofs;
      res.found += best_iou[size_t(b)] >= 0.5;
      if (verbose && best_iou[size_t(b)] < 0.5)
        std::printf("    missed building %d (%s, %s, %d px, colour %d,%d,%d): best IoU %.2f\n", b,
                    city.shapes[size_t(b)].c_str(), RoofTypeName(city.roofs[size_t(b)]), visible[size_t(b)],
                    city.roof_colours[size_t(b)][0], city.roof_colours[size_t(b)][1], city.roof_colours[size_t(b)][2],
                    best_iou[size_t(b)]);
    }
    std::printf("%6llu %4dx%-5d %6.2f %8d %8d %8d %8d %8d %8.1f\n", (unsigned long long)seed, res.size.width,
                res.size.height, res.scale, res.roofs, res.found, res.regions, res.false_regions, res.road_regions,
                res.ms);
    std::fflush(stdout);
    if (!draw_dir.empty()) {
      std::filesystem::create_directories(draw_dir);
      cv::Mat3b out = photo.clone();
      // Ground truth outlines (thin white, buildings inside the depth raster), road edges (dark).
      cv::Mat1b gt = ids >= 0, edges;
      cv::morphologyEx(gt, edges, cv::MORPH_GRADIENT, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
      out.setTo(cv::Scalar(255, 255, 255), edges & gt);
      cv::morphologyEx(road, edges, cv::MORPH_GRADIENT, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
      out.setTo(cv::Scalar(0, 128, 255), edges & road);
      for (size_t i = 0; i < regions.size(); ++i) {
        const cv::Scalar col = kind[i] == 1 ? cv::Scalar(0, 220, 0) : kind[i] == 2 ? cv::Scalar(0, 0, 255)
                                                                                  : cv::Scalar(255, 80, 0);
        cv::polylines(out, regions[i].contour, true, col, 2);
      }
      cv::imwrite(draw_dir + "/seed_" + std::to_string(seed) + ".png", out);
    }
    if (!maps_dir.empty()) {
      std::filesystem::create_directories(maps_dir);
      cv::imwrite(maps_dir + "/maps_" + std::to_string(seed) + ".png", DrawOpticalMaps(photo, opt));
    }
    results.push_back(res);
  }

  SeedResult tot;
  std::vector<double> ms;
  for (const SeedResult& r : results) {
    tot.roofs += r.roofs, tot.found += r.found, tot.regions += r.regions;
    tot.false_regions += r.false_regions, tot.road_regions += r.road_regions;
    ms.push_back(r.ms);
  }
  std::sort(ms.begin(), ms.end());
  double mean_ms = 0;
  for (double m : ms) mean_ms += m;
  mean_ms /= std::max<size_t>(1, ms.size());
  const double found_pct = 100.0 * tot.found / std::max(1, tot.roofs);
  const double false_pct = 100.0 * tot.false_regions / std::max(1, tot.regions);
  const double road_pct = 100.0 * tot.road_regions / std::max(1, tot.regions);
  std::printf("overall seeds %llu-%llu: roofs found %d/%d (%.1f %%), false regions %d/%d (%.1f %%), "
              "on roads %d (%.1f %%), ms mean %.1f median %.1f max %.1f\n",
              (unsigned long long)seeds[0], (unsigned long long)seeds[1], tot.found, tot.roofs, found_pct,
              tot.false_regions, tot.regions, false_pct, tot.road_regions, road_pct, mean_ms,
              ms.empty() ? 0 : ms[ms.size() / 2], ms.empty() ? 0 : ms.back());
  if (!json_path.empty()) {
    nlohmann::json j;
    for (const SeedResult& r : results)
      j["seeds"].push_back({{"seed", r.seed}, {"width", r.size.width}, {"height", r.size.height}, {"scale", r.scale},
                            {"roofs", r.roofs}, {"found", r.found}, {"regions", r.regions},
                            {"false_regions", r.false_regions}, {"road_regions", r.road_regions}, {"ms", r.ms}});
    j["overall"] = {{"roofs", tot.roofs}, {"found", tot.found}, {"found_pct", found_pct},
                    {"regions", tot.regions}, {"false_regions", tot.false_regions}, {"false_pct", false_pct},
                    {"road_regions", tot.road_regions}, {"road_pct", road_pct}, {"ms_mean", mean_ms}};
    std::ofstream(json_path) << j.dump(2) << "\n";
  }
  return 0;
}
