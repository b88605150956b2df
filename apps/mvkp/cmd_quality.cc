// mvkp quality: how well images will be recognised as targets (0-100, with reasons).
#include <cstdio>
#include <iostream>
#include <memory>

#include "commands.h"
#include "mvkp/core/image_io.h"
#include "mvkp/quality/quality.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct QualityArgs {
  std::vector<std::string> images;
  bool json = false;
  std::string draw;
  bool affine = false;
  QualityOptions opt;
};

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
  for (const auto& f : r.factors)
    std::printf("  %-16s %5.1f / %4.0f points  (measured %.3g)\n", f.name.c_str(), f.points, 100 * f.weight, f.value);
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
      const cv::Mat gray = LoadImageGray(path);
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
  c->add_option("IMAGE", a->images, "candidate target images")->required();
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
