// mvkp eval: accuracy of MVKP and OpenCV baselines on image pairs with
// ground-truth homographies (manifests of `img1 img2 H`, as `mvkp synth`
// writes and eval_pairs.py reads). Trains once per distinct img1.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>

#include <opencv2/calib3d.hpp>

#include "baselines.h"
#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/match/matcher.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::vector<std::string> manifests;
  std::vector<std::string> baselines;
  std::string json_out;
  bool per_pair = false;
  bool affine = false;
  TrainOptions train;
  MatchOptions match;
};

struct Row {
  std::string method, set, pair;
  double corner_err = INFINITY;
  int matches = 0, inliers = 0, correct = 0;
  double ms = 0;
};

int Correct(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b, const cv::Matx33d& H) {
  if (a.empty()) return 0;
  std::vector<cv::Point2f> p;
  cv::perspectiveTransform(a, p, cv::Mat(H));
  int n = 0;
  for (std::size_t i = 0; i < a.size(); ++i) n += cv::norm(p[i] - b[i]) < 3.0;
  return n;
}

int RunEval(EvalArgs& a) {
  if (a.affine) a.match.geometry = GeometryModel::kAffine;
  std::vector<ManifestPair> pairs;
  for (const auto& m : a.manifests) {
    auto p = ReadManifest(m);  // baselines.h
    pairs.insert(pairs.end(), p.begin(), p.end());
  }
  std::vector<Row> rows;
  std::map<std::string, std::unique_ptr<Matcher>> matchers;
  std::map<std::string, std::vector<std::unique_ptr<Baseline>>> bases;
  std::map<std::string, cv::Size> sizes;
  std::vector<double> train_ms;
  std::vector<std::string> methods = {"mvkp"};
  for (const auto& b : a.baselines) methods.push_back("opencv-" + b);
  int done = 0;
  for (const auto& p : pairs) {
    if (!matchers.count(p.img1)) {
      const cv::Mat obj = LoadImageGray(p.img1);
      sizes[p.img1] = obj.size();
      Timer t;
      matchers[p.img1] = std::make_unique<Matcher>(TrainNamed(p.img1, obj, a.train), a.match);
      train_ms.push_back(t.ElapsedMs());
      for (const auto& b : a.baselines) {
        bases[p.img1].push_back(std::make_unique<Baseline>(b));
        bases[p.img1].back()->Prepare(obj);
      }
    }
    const cv::Mat frame = LoadImageGray(p.img2);
    const bool gt = p.h != "none";
    const cv::Matx33d H = gt ? ReadHomography(p.h) : cv::Matx33d::eye();
    const std::string name = fs::path(p.img1).filename().string() + " " + fs::path(p.img2).filename().string();
    {
      const MatchResult r = matchers[p.img1]->Match(frame);
      Row row{"mvkp", p.set, name};
      row.matches = int(r.matches.size());
      row.inliers = r.inliers;
      row.ms = r.time.total();
      if (gt && r.found) row.corner_err = MeanCornerError(r.homography, H, sizes[p.img1]);
      std::vector<cv::Point2f> oa, qb;
      for (const auto& m : r.matches) {
        oa.push_back(m.object);
        qb.push_back(m.query);
      }
      if (gt) row.correct = Correct(oa, qb, H);
      rows.push_back(row);
    }
    for (const auto& b : bases[p.img1]) {
      const BaselineResult r = b->Frame(frame);
      Row row{b->name(), p.set, name};
      row.matches = int(r.object_pts.size());
      row.inliers = int(std::count(r.inlier.begin(), r.inlier.end(), 1));
      row.ms = r.ms;
      if (gt && r.found) row.corner_err = MeanCornerError(r.homography, H, sizes[p.img1]);
      if (gt) row.correct = Correct(r.object_pts, r.query_pts, H);
      rows.push_back(row);
    }
    Progress("eval: pair", ++done, int(pairs.size()));
  }

  if (a.per_pair)
    for (const auto& r : rows)
      std::printf("%-14s %-12s %-34s err %8.2f  matches %4d  correct %4d  inliers %4d  %7.2f ms\n", r.method.c_str(),
                  r.set.c_str(), r.pair.c_str(), std::min(r.corner_err, 9999.0), r.matches, r.correct, r.inliers, r.ms);
  std::printf("%-14s %6s %8s %8s %9s %9s %9s\n", "method", "pairs", "ok@5px", "ok@10px", "correct", "inliers", "ms");
  nlohmann::json summary;
  for (const auto& m : methods) {
    int n = 0, ok5 = 0, ok10 = 0;
    double corr = 0, inl = 0;
    std::vector<double> ms;
    for (const auto& r : rows)
      if (r.method == m) {
        ++n;
        ok5 += r.corner_err < 5;
        ok10 += r.corner_err < 10;
        corr += r.correct;
        inl += r.inliers;
        ms.push_back(r.ms);
      }
    if (!n) continue;
    std::printf("%-14s %6d %8.3f %8.3f %9.1f %9.1f %9.2f\n", m.c_str(), n, double(ok5) / n, double(ok10) / n, corr / n,
                inl / n, Median(ms));
    summary[m] = {{"pairs", n}, {"ok5", double(ok5) / n}, {"ok10", double(ok10) / n}, {"correct", corr / n},
                  {"inliers", inl / n}, {"median_ms", Median(ms)}};
  }
  std::printf("mvkp training: %s, median %.0f ms\n", Count(train_ms.size(), "target").c_str(), Median(train_ms));
  if (!a.json_out.empty()) {
    nlohmann::json j = {{"summary", summary}, {"train_ms_median", Median(train_ms)}};
    for (const auto& r : rows)
      j["rows"].push_back({{"method", r.method}, {"set", r.set}, {"pair", r.pair},
                           {"corner_err", std::isfinite(r.corner_err) ? nlohmann::json(r.corner_err) : nlohmann::json(nullptr)},
                           {"matches", r.matches}, {"correct", r.correct}, {"inliers", r.inliers}, {"ms", r.ms}});
    std::ofstream(a.json_out) << j.dump(1) << "\n";
  }
  return 0;
}

}  // namespace

void RegisterEval(CLI::App& app, int* code) {
  auto a = std::make_shared<EvalArgs>();
  auto* c = app.add_subcommand("eval", "Score MVKP (and OpenCV baselines) on manifests of 'img1 img2 H' pairs");
  c->add_option("MANIFEST", a->manifests, "manifest files (e.g. from 'mvkp synth')");
  c->add_option("--baselines", a->baselines, "OpenCV pipelines run in the same pass: sift orb akaze brisk")->delimiter(',');
  c->add_option("--json", a->json_out, "write per-pair rows and the summary here");
  c->add_flag("--per-pair", a->per_pair, "print every pair");
  AddTrainOptions(c, &a->train);
  AddMatchOptions(c, &a->match, &a->affine);
  RegisterEvalOxford(c, code);
  RegisterEvalSweep(c, code);
  c->require_subcommand(0, 1);
  c->callback([a, c, code] {
    if (c->got_subcommand("oxford") || c->got_subcommand("sweep")) return;  // its own callback ran
    if (a->manifests.empty()) throw CLI::RequiredError("MANIFEST");
    *code = RunEval(*a);
  });
}

}  // namespace mvkp::cli
