// mvkp synth-city: synthetic cities (LiDAR depth raster + aerial photo + ground
// truth) for testing photo <-> LiDAR registration at scale (issue 8).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/core/error.h"

namespace mvkp::cli {

void RegisterSynthCity(CLI::App& app, int* code);

namespace {

struct SynthCityArgs {
  std::string outdir;
  int n = 1;
  std::uint64_t seed = 1;
  int max_buildings = -1;  // > 0: scene i has buildings..max_buildings buildings (from its seed)
  CityOptions opt;
};

int RunSynthCity(SynthCityArgs& a) {
  Require(a.n >= 1 && a.n <= 100000, ErrorCode::kInvalidArgument, "--n must be in 1..100000");
  a.opt.Check();
  Require(a.max_buildings < 0 || (a.max_buildings >= a.opt.buildings && a.max_buildings <= 5000),
          ErrorCode::kInvalidArgument, "--max-buildings must be >= --buildings and <= 5000");
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(a.outdir, ec);
  if (ec || !fs::is_directory(a.outdir)) throw Error(ErrorCode::kIo, a.outdir + ": cannot create output directory");
  for (int i = 0; i < a.n; ++i) {
    const std::uint64_t seed = a.seed * 1000003ull + std::uint64_t(i);
    const auto t0 = std::chrono::steady_clock::now();
    CityOptions opt = a.opt;
    if (a.max_buildings >= 0) opt.buildings += int(seed % std::uint64_t(a.max_buildings - a.opt.buildings + 1));
    const City c = MakeCity(opt, seed);
    char name[32];
    std::snprintf(name, sizeof name, "city_%04d", i);
    const std::string dir = (fs::path(a.outdir) / name).string();
    SaveCity(c, dir);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const nlohmann::json j = {{"scene", name},
                              {"dir", dir},
                              {"seed", seed},
                              {"buildings", c.footprints.size()},
                              {"corners", c.corners.size()},
                              {"outside_buildings", c.outside_buildings},
                              {"depth", {c.depth.cols, c.depth.rows}},
                              {"photo", {c.photo.cols, c.photo.rows}},
                              {"scale", c.scale},
                              {"rotation_deg", c.rotation_deg},
                              {"overlap", a.opt.overlap},
                              {"style", a.opt.style},
                              {"photo_overlap", c.photo_overlap},
                              {"depth_overlap", c.depth_overlap},
                              {"ms", std::round(ms)}};
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

void RegisterSynthCity(CLI::App& app, int* code) {
  auto a = std::make_shared<SynthCityArgs>();
  CityOptions& o = a->opt;
  auto* c = app.add_subcommand(
      "synth-city",
      "Write synthetic cities: LiDAR-like depth raster (depth.tif), aerial photo (photo.png) and ground truth "
      "(truth.json: photo->depth homography, building footprints and corners) in DIR/city_NNNN/");
  c->add_option("-o,--output", a->outdir, "output directory")->required();
  c->add_option("--n", a->n, "number of scenes")->capture_default_str();
  c->add_option("--seed", a->seed, "random seed (scene i uses seed * 1000003 + i)")->capture_default_str();
  c->add_option("--buildings", o.buildings, "buildings inside the depth raster")->capture_default_str();
  c->add_option("--max-buildings", a->max_buildings,
                 "with it, each scene has --buildings..--max-buildings buildings (chosen from the scene's seed)");
  c->add_option("--trees", o.trees, "trees inside the depth raster")->capture_default_str();
  c->add_option("--width", o.width, "depth raster width (pixels)")->capture_default_str();
  c->add_option("--height", o.height, "depth raster height (pixels)")->capture_default_str();
  c->add_option("--res", o.res_m, "depth raster resolution (metres per pixel)")->capture_default_str();
  c->add_option("--min-scale", o.min_scale, "smallest photo->depth scale")->capture_default_str();
  c->add_option("--max-scale", o.max_scale, "largest photo->depth scale")->capture_default_str();
  c->add_option("--perspective", o.max_perspective, "max perspective (relative divisor change over the photo)")
      ->capture_default_str();
  c->add_option("--sun-azimuth", o.sun_azimuth_deg, "sun azimuth in degrees from north (negative: random)")
      ->capture_default_str();
  c->add_option("--sun-elevation", o.sun_elevation_deg, "sun elevation in degrees (negative: random in 30..65)")
      ->capture_default_str();
  c->add_option("--missing", o.missing_returns, "fraction of depth pixels without a LiDAR return")->capture_default_str();
  c->add_option("--depth-noise", o.depth_noise_m, "LiDAR noise sigma (metres)")->capture_default_str();
  c->add_option("--photo-max-side", o.photo_max_side, "longest photo side (pixels)")->capture_default_str();
  c->add_option("--min-coverage", o.min_coverage, "smallest photo ground side / depth raster side")->capture_default_str();
  c->add_option("--max-coverage", o.max_coverage, "largest photo ground side / depth raster side")->capture_default_str();
  c->add_option("--blur", o.photo_blur, "max photo blur sigma (pixels)")->capture_default_str();
  c->add_option("--noise", o.photo_noise, "max photo noise sigma (grey levels)")->capture_default_str();
  c->add_flag("!--no-overlap", o.overlap, "the photo shows a different area (negative tests)");
  c->add_flag("!--no-pitched", o.pitched_roofs, "flat roofs only");
  c->add_option("--style", o.style,
                "classic (the original generator), suburb (houses, gardens, hedges, pools, two street grids), dense "
                "(bars, blocks, halls with parking lots, dark roofs) or civic (round and star-shaped buildings among "
                "both); every style but classic has hilly ground, moved cars and a leaning (not true) orthophoto")
      ->check(CLI::IsMember(CityStyles()))
      ->capture_default_str();
  c->callback([a, code] { *code = RunSynthCity(*a); });
}

}  // namespace mvkp::cli
