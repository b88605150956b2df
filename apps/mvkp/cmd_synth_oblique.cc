// mvkp synth-oblique: oblique views of synthetic cities with exact ground
// truth (camera matrix, check points), for registering oblique photos to the
// nadir photo and the LiDAR (issue 22, thesis §7.3).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mvkp/city/synth_city.h"
#include "mvkp/city/synth_oblique.h"
#include "mvkp/core/error.h"

namespace mvkp::cli {

void RegisterSynthOblique(CLI::App& app, int* code);

namespace {

struct SynthObliqueArgs {
  std::string outdir;
  int n = 1, views = 4;
  std::uint64_t seed = 1;
  std::vector<double> tilt{30, 60};   // range, degrees off nadir
  std::vector<double> gsd{0.15, 0.6};  // range, metres per pixel
  double azimuth = -1;                 // < 0: random
  CityOptions city;
  ObliqueOptions view;
};

int RunSynthOblique(SynthObliqueArgs& a) {
  Require(a.n >= 1 && a.n <= 10000, ErrorCode::kInvalidArgument, "--n must be in 1..10000");
  Require(a.views >= 1 && a.views <= 100, ErrorCode::kInvalidArgument, "--views must be in 1..100");
  Require(a.tilt.size() == 2 && a.tilt[0] <= a.tilt[1] && a.tilt[0] >= 0 && a.tilt[1] <= 75,
          ErrorCode::kInvalidArgument, "--tilt takes MIN MAX within [0, 75] degrees");
  Require(a.gsd.size() == 2 && a.gsd[0] <= a.gsd[1] && a.gsd[0] >= 0.02 && a.gsd[1] <= 5, ErrorCode::kInvalidArgument,
          "--gsd takes MIN MAX within [0.02, 5] metres per pixel");
  a.city.Check();
  a.view.Check();
  namespace fs = std::filesystem;
  for (int i = 0; i < a.n; ++i) {
    const std::uint64_t seed = a.seed * 1000003ull + std::uint64_t(i);
    const City c = MakeCity(a.city, seed);
    char name[32];
    std::snprintf(name, sizeof name, "city_%04d", i);
    const std::string dir = (fs::path(a.outdir) / name).string();
    SaveCity(c, dir);
    std::mt19937_64 g(seed ^ 0x0b11c0eull);
    auto U = [&](double lo, double hi) { return lo + (hi - lo) * double(g() >> 11) * 0x1.0p-53; };
    for (int k = 0; k < a.views; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      ObliqueOptions o = a.view;
      o.tilt_deg = U(a.tilt[0], a.tilt[1]);
      o.azimuth_deg = a.azimuth >= 0 ? a.azimuth : U(0, 360);
      o.gsd_m = std::exp(U(std::log(a.gsd[0]), std::log(a.gsd[1])));
      const ObliqueView v = RenderOblique(c, o, seed * 131 + std::uint64_t(k));
      char stem[32];
      std::snprintf(stem, sizeof stem, "oblique_%02d", k);
      SaveOblique(v, dir, stem);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const nlohmann::json j = {{"scene", name},          {"view", stem},
                                {"dir", dir},             {"tilt_deg", o.tilt_deg},
                                {"azimuth_deg", o.azimuth_deg}, {"gsd_m", o.gsd_m},
                                {"check_points", v.checks.size()}, {"ms", std::round(ms)}};
      std::printf("%s\n", j.dump().c_str());
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace

void RegisterSynthOblique(CLI::App& app, int* code) {
  auto a = std::make_shared<SynthObliqueArgs>();
  auto* c = app.add_subcommand(
      "synth-oblique",
      "Write synthetic cities (as synth-city) with oblique views of each: DIR/city_NNNN/oblique_KK.png and "
      "oblique_KK.json (3x4 camera matrix from world metres to pixels, visible check points with their depth, "
      "nadir-photo and oblique pixels)");
  c->add_option("-o,--output", a->outdir, "output directory")->required();
  c->add_option("--n", a->n, "number of cities")->capture_default_str();
  c->add_option("--views", a->views, "oblique views per city")->capture_default_str();
  c->add_option("--seed", a->seed, "random seed (city i uses seed * 1000003 + i)")->capture_default_str();
  c->add_option("--style", a->city.style, "city style: classic, suburb, dense or civic")
      ->check(CLI::IsMember(CityStyles()))
      ->capture_default_str();
  c->add_option("--buildings", a->city.buildings, "buildings inside the depth raster")->capture_default_str();
  c->add_option("--tilt", a->tilt, "tilt range off nadir, degrees (MIN MAX)")->expected(2)->capture_default_str();
  c->add_option("--gsd", a->gsd, "ground sampling distance range at the image centre, m/px (MIN MAX)")
      ->expected(2)
      ->capture_default_str();
  c->add_option("--azimuth", a->azimuth, "viewing azimuth, degrees from north (negative: random)")
      ->capture_default_str();
  c->add_option("--width", a->view.width, "view width (pixels)")->capture_default_str();
  c->add_option("--height", a->view.height, "view height (pixels)")->capture_default_str();
  c->add_option("--hfov", a->view.hfov_deg, "horizontal field of view, degrees")->capture_default_str();
  c->add_option("--check-points", a->view.check_points, "check points per view (at most)")->capture_default_str();
  c->callback([a, code] { *code = RunSynthOblique(*a); });
}

}  // namespace mvkp::cli
