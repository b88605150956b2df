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

  std::vector<double> det, desc, search, verify, total;
  int found = 0;
  for (int r = 0; r < a.repeat; ++r)
    for (const auto& f : frames) {
      const MatchResult m = matcher.Match(f);
      det.push_back(m.time.smooth_ms + m.time.detect_ms);
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
  sides.push_back({Baseline("sift", a.features), {}, 0});
  sides.push_back({Baseline("orb", a.features), {}, 0});
  for (Side& s : sides) {
    s.b.Prepare(object);
    for (int r = 0; r < a.repeat; ++r)
      for (const auto& f : frames) {
        const BaselineResult br = s.b.Frame(f);
        s.ms.push_back(br.ms);
        if (r == 0) s.found += br.found && std::count(br.inlier.begin(), br.inlier.end(), 1) >= 10;
      }
  }
  Side& sift = sides[0];
  Side& orb = sides[1];
  const double mv = Median(total), sv = Median(sift.ms), ov = Median(orb.ms);
  if (a.json) {
    nlohmann::json j = {
        {"target", a.image}, {"frames", frames.size()}, {"repeat", a.repeat},
        {"train_ms", Median(train_ms)}, {"model_bytes", model_bytes},
        {"mvkp", {{"detect", Median(det)}, {"describe", Median(desc)}, {"search", Median(search)},
                  {"verify", Median(verify)}, {"query", mv}, {"found", found}}},
        {"opencv-sift", {{"query", sv}, {"found", sift.found}}},
        {"opencv-orb", {{"query", ov}, {"found", orb.found}, {"features", a.features}}},
        {"ratio_sift_over_mvkp", sv / mv}, {"ratio_orb_over_mvkp", ov / mv}};
    std::cout << j.dump(1) << std::endl;
    return 0;
  }
  std::printf("mvkp bench: target %s (%dx%d), %zu frames x %d repeats, single thread, medians\n", a.image.c_str(),
              object.cols, object.rows, frames.size(), a.repeat);
  std::printf("  training     %9.1f ms   (%d views; model %.1f KB)\n", Median(train_ms), a.train.views,
              model_bytes / 1024.0);
  std::printf("  per frame    detect %.2f  describe %.2f  search %.2f  verify %.2f ms\n", Median(det), Median(desc),
              Median(search), Median(verify));
  std::printf("  %-12s %9.2f ms/frame   found %d/%zu\n", "mvkp", mv, found, frames.size());
  std::printf("  %-12s %9.2f ms/frame   found %d/%zu   %.1fx mvkp\n", "opencv-sift", sv, sift.found, frames.size(), sv / mv);
  std::printf("  %-12s %9.2f ms/frame   found %d/%zu   %.1fx mvkp   (%d features)\n", "opencv-orb", ov, orb.found,
              frames.size(), ov / mv, a.features);
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
  c->add_flag("--json", a->json, "machine-readable output");
  AddTrainOptions(c, &a->train);
  AddMatchOptions(c, &a->match, &a->affine);
  c->callback([a, code] { *code = RunBench(*a); });
}

}  // namespace mvkp::cli
