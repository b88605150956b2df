// mvkp quality: how well images will be recognised as targets (0-100, with
// reasons); for a target database, every exhibit's score and the exhibits
// that look alike.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/db/target_store.h"
#include "mvkp/quality/db_quality.h"
#include "mvkp/quality/quality.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct QualityArgs {
  std::vector<std::string> images;
  bool json = false;
  std::string draw;
  bool affine = false;
  int views = DatabaseQualityOptions{}.synthetic_views;
  QualityOptions opt;
};

// Whether `path` is an SQLite file (a target database, or a damaged one):
// then it is opened as a database and its errors are the answer.
bool IsSqliteFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[16] = {};
  in.read(magic, sizeof magic);
  return in.gcount() == 16 && std::memcmp(magic, "SQLite format 3", 16) == 0;
}

void PrintDatabase(const DatabaseQualityReport& r) {
  std::printf("%s: %zu exhibits\n", r.db.c_str(), r.exhibits.size());
  double q_ms = 0, p_ms = 0;
  for (const auto& e : r.exhibits) {
    if (e.assessed)
      std::printf("  %-24s quality %3d/100 (%s), detection %.0f%%, %d stable points at %d px\n", e.info.id.c_str(),
                  e.quality.score, e.quality.verdict.c_str(), 100 * e.quality.detection_rate, e.quality.eligible_tracks,
                  e.quality.train_side);
    else std::printf("  %-24s not assessed\n", e.info.id.c_str());
    if (!e.error.empty()) std::printf("    error: %s\n", e.error.c_str());
    q_ms += e.quality_ms;
    p_ms += e.probe_ms;
  }
  if (r.pairs.empty()) std::printf("no exhibits look alike\n");
  else std::printf("look-alikes (recognising A's image and views finds B instead):\n");
  for (const auto& p : r.pairs)
    std::printf("  %s -> %s: found in %d of %d probes, up to %d inliers\n", p.a.c_str(), p.b.c_str(), p.found_in,
                p.probes, p.inliers);
  const double n = std::max<std::size_t>(1, r.exhibits.size());
  std::printf("  %.1f s (per exhibit: quality %.0f ms, look-alike search %.0f ms)\n", r.ms / 1000, q_ms / n, p_ms / n);
}

nlohmann::json ImageQualityJson(const std::string& image, const QualityReport& r) {
  nlohmann::json j = QualityJson(r, /*with_points=*/true);
  j["image"] = image;
  return j;
}

void PrintText(const std::string& image, const QualityReport& r) {
  std::printf("%s: quality %d/100 (%s)\n", image.c_str(), r.score, r.verdict.c_str());
  if (r.test_views > 0 && !r.factors.empty())
    std::printf("  expected detection rate %.0f%% (%d synthetic views, success = corner error < 5 px)\n",
                100 * r.detection_rate, r.test_views);
  for (const auto& f : r.factors) {
    std::printf("  %-16s %5.1f / %4.0f points  (measured %.3g", f.name.c_str(), f.points, 100 * f.weight, f.value);
    // The count depends on the training size (`mvkp db add` trains smaller).
    if (f.name == "stable_points" && r.train_side > 0) std::printf(" at %d px", r.train_side);
    std::printf(")\n");
  }
  if (r.reasons.empty()) std::printf("  no weaknesses found\n");
  for (const auto& q : r.reasons) {
    if (q.lost >= 0.5) std::printf("  - %s (-%.0f): %s\n", q.code.c_str(), q.lost, q.message.c_str());
    else std::printf("  - %s: %s\n", q.code.c_str(), q.message.c_str());
  }
  std::printf("  %.0f ms\n", r.ms);
}

int RunQuality(QualityArgs& a) {
  if (a.affine) a.opt.match.geometry = GeometryModel::kAffine;
  a.opt.Check();
  int failures = 0;
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    const std::string& path = a.images[i];
    try {
      if (IsSqliteFile(path)) {
        DatabaseQualityOptions d;
        d.quality = a.opt;
        d.synthetic_views = a.views;
        const DatabaseQualityReport r = AssessDatabase(path, d);
        if (a.json) std::cout << DatabaseQualityJson(r).dump() << std::endl;
        else PrintDatabase(r);
        continue;
      }
      cv::Mat gray;
      try {
        gray = LoadImageGray(path);
      } catch (const Error& e) {
        // A file of no known image format may be a database given by mistake.
        if (e.code() != ErrorCode::kBadImage || std::string(e.what()).find("not an image") == std::string::npos) throw;
        throw Error(e.code(), std::string(e.what()) + "; nor an mvkp target database");
      }
      const QualityReport r = AssessTarget(gray, a.opt);
      if (a.json) std::cout << ImageQualityJson(path, r).dump() << std::endl;
      else PrintText(path, r);
      if (!a.draw.empty())
        SaveImage(IndexedPath(a.draw, int(i), int(a.images.size())), DrawQuality(LoadImageColor(path), r));
    } catch (const std::exception& e) {
      ++failures;
      std::fprintf(stderr, "mvkp quality: %s\n", e.what());
      if (a.json) std::cout << nlohmann::json{{"image", path}, {"error", e.what()}}.dump() << std::endl;
    }
  }
  return failures ? 1 : 0;
}

}  // namespace

void RegisterQuality(CLI::App& app, int* code) {
  auto a = std::make_shared<QualityArgs>();
  auto* c = app.add_subcommand("quality", "Score images as targets (0-100) with the reasons and expected detection rate");
  c->add_option("IMAGE", a->images, "candidate target images, or target databases (every exhibit's score and the look-alike pairs)")->required();
  c->add_option("--lookalike-views", a->views, "databases: synthetic views per exhibit for the look-alike search (0-16)")->capture_default_str();
  c->add_flag("--json", a->json, "one JSON object per line, per image");
  c->add_option("--draw", a->draw, "write the image with the selected features marked (-N suffix for several)");
  c->add_option("--test-views", a->opt.test_views, "synthetic views for the detection rate")->capture_default_str();
  c->add_option("--test-seed", a->opt.seed, "seed of the synthetic test views")->capture_default_str();
  c->add_option("--target-size", a->opt.target_size, "assess at this longest side (mvkp synth's default)")->capture_default_str();
  AddTrainOptions(c, &a->opt.train);
  AddMatchOptions(c, &a->opt.match, &a->affine);
  c->callback([a, code] { *code = RunQuality(*a); });
}

}  // namespace mvkp::cli
