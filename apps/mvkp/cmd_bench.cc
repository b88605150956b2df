// mvkp bench: training time and per-frame query time of MVKP, split by stage,
// side by side with OpenCV SIFT and ORB on the same frames, single thread.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>

#include "baselines.h"
#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct BenchArgs {
  std::string image;
  std::vector<std::string> queries;
  int repeat = 5;
  int train_repeat = 3;
  int features = 2000;
  std::vector<std::string> baselines = {"sift", "orb"};
  bool json = false;
  bool affine = false;
  TrainOptions train;
  MatchOptions match;
};

int RunBench(BenchArgs& a) {
  Require(a.repeat >= 1 && a.train_repeat >= 1, ErrorCode::kInvalidArgument, "--repeat and --train-repeat must be >= 1");
  const cv::Mat object = LoadImageGray(a.image);
  std::vector<cv::Mat> frames;
  for (const auto& q : a.queries) frames.push_back(LoadImageGray(q));
  if (a.affine) a.match.geometry = GeometryModel::kAffine;

  std::vector<double> train_ms;
  Model model;
  for (int i = 0; i < a.train_repeat; ++i) {
    Timer t;
    model = TrainNamed(a.image, object, a.train);
    train_ms.push_back(t.ElapsedMs());
  }
  const std::size_t model_bytes = SerializeModel(model).size();
  const Matcher matcher(model, a.match);

  std::vector<double> det, smooth, desc, search, verify, total;
  int found = 0;
  for (int r = 0; r < a.repeat; ++r)
    for (const auto& f : frames) {
      const MatchResult m = matcher.Match(f);
      det.push_back(m.time.smooth_ms + m.time.detect_ms);
      smooth.push_back(m.time.smooth_ms);
      desc.push_back(m.time.describe_ms);
      search.push_back(m.time.search_ms);
      verify.push_back(m.time.verify_ms);
      total.push_back(m.time.total());
      found += r == 0 && m.found;
    }

  struct Side {
    Baseline b;
    std::vector<double> ms;
    int found = 0;
  };
  std::vector<Side> sides;
  for (const auto& b : a.baselines)
    if (b != "none") sides.push_back({Baseline(b, a.features), {}, 0});
  for (Side& s : sides) {
    s.b.Prepare(object);
    for (int r = 0; r < a.repeat; ++r)
      for (const auto& f : frames) {
        const BaselineResult br = s.b.Frame(f);
        s.ms.push_back(br.ms);
        if (r == 0) s.found += br.found && std::count(br.inlier.begin(), br.inlier.end(), 1) >= 10;
      }
  }
  const double mv = Median(total);
  if (a.json) {
    nlohmann::json j = {
        {"target", a.image}, {"frames", frames.size()}, {"repeat", a.repeat},
        {"train_ms", Median(train_ms)}, {"model_bytes", model_bytes},
        {"mvkp", {{"detect", Median(det)}, {"describe", Median(desc)}, {"search", Median(search)},
                  {"verify", Median(verify)}, {"query", mv}, {"found", found}}}};
    for (const Side& s : sides) {
      const double v = Median(s.ms);
      j[s.b.name()] = {{"query", v}, {"found", s.found}, {"features", a.features}};
      j["ratio_" + s.b.name().substr(7) + "_over_mvkp"] = v / mv;
    }
    std::cout << j.dump(1) << std::endl;
    return 0;
  }
  std::printf("mvkp bench: target %s (%dx%d), %zu frames x %d repeats, single thread, medians\n", a.image.c_str(),
              object.cols, object.rows, frames.size(), a.repeat);
  std::printf("  training     %9.1f ms   (%d views; model %.1f KB)\n", Median(train_ms), a.train.views,
              model_bytes / 1024.0);
  std::printf("  per frame    detect %.2f (smoothing and resampling %.2f)  describe %.2f  search %.2f  verify %.2f ms\n",
              Median(det), Median(smooth), Median(desc), Median(search), Median(verify));
  std::printf("  %-12s %9.2f ms/frame   found %d/%zu\n", "mvkp", mv, found, frames.size());
  for (const Side& s : sides) {
    const double v = Median(s.ms);
    std::printf("  %-12s %9.2f ms/frame   found %d/%zu   %.1fx mvkp   (%d features)\n", s.b.name().c_str(), v, s.found,
                frames.size(), v / mv, a.features);
  }
  return 0;
}

}  // namespace

void RegisterBench(CLI::App& app, int* code) {
  auto a = std::make_shared<BenchArgs>();
  auto* c = app.add_subcommand("bench", "Time training and per-frame queries against OpenCV SIFT and ORB");
  c->add_option("IMAGE", a->image, "target image")->required();
  c->add_option("QUERY", a->queries, "query frames")->required();
  c->add_option("--repeat", a->repeat, "passes over the frames")->capture_default_str();
  c->add_option("--train-repeat", a->train_repeat, "trainings timed")->capture_default_str();
  c->add_option("--features", a->features, "SIFT/ORB features per image")->capture_default_str();
  c->add_option("--baselines", a->baselines, "OpenCV pipelines timed on the same frames: sift orb akaze brisk asift, or none")
      ->delimiter(',')
      ->capture_default_str();
  c->add_flag("--json", a->json, "machine-readable output");
  AddTrainOptions(c, &a->train);
  AddMatchOptions(c, &a->match, &a->affine);
  c->callback([a, code] { *code = RunBench(*a); });
}

}  // namespace mvkp::cli
