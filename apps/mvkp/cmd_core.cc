// mvkp train / match / pair.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include <opencv2/core.hpp>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/local/local_features.h"
#include "mvkp/local/pair_match.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct TrainArgs {
  std::string image, output;
  bool quiet = false;
  bool explain = false;
  int explain_rows = 40;
  TrainOptions opt;
};

struct MatchArgs {
  std::string model;
  std::vector<std::string> queries;
  bool json = false;
  std::string draw;
  bool affine = false;
  MatchOptions opt;
};

struct PairArgs {
  std::string image1, image2;
  std::string method = "mvkp";
  CLI::Option* ratio_option = nullptr;  // to tell whether --ratio was given
  bool json = false;
  std::string draw;
  bool affine = false;
  TrainOptions train;
  MatchOptions match;
};

// Per-track scores in the style of thesis Table 3.1.
void PrintExplain(const TrainReport& r, int rows) {
  std::printf("view tracks: %d candidates, %d eligible (SS >= L_SS = %d of %d views: %d general + %d rotation), %d kept\n",
              r.candidates, r.eligible, r.min_stability, r.general_views + r.rotation_views, r.general_views,
              r.rotation_views, r.kept);
  std::printf("ranking: %s, alpha %.2f: FRS = alpha*RRS' + (1-alpha)*SS, RRS = DS/VS rescaled to [L_SS, N_V]\n",
              SelectionName(r.select), r.alpha);
  std::printf("%5s %8s %8s %4s %5s %8s %9s %9s %7s %7s %5s\n", "rank", "x", "y", "SS", "gen", "DS", "VS", "RRS",
              "RRS'", "FRS", "kept");
  const int n = rows < 0 ? int(r.tracks.size()) : std::min<int>(rows, int(r.tracks.size()));
  auto line = [](const TrackReport& t) {
    if (t.rank < 0) {
      std::printf("%5s %8.1f %8.1f %4d %5d %8s %9s %9s %7s %7s %5s\n", "-", t.x, t.y, t.score.ss, t.general, "-", "-",
                  "-", "-", "-", "no");
      return;
    }
    std::printf("%5d %8.1f %8.1f %4d %5d %8.4f %9.6f %9.2f %7.2f %7.2f %5s\n", t.rank + 1, t.x, t.y, t.score.ss,
                t.general, t.score.ds, t.score.vs, t.score.rrs, t.score.rrs_scaled, t.score.frs, t.kept ? "yes" : "no");
  };
  for (int i = 0; i < n; ++i) line(r.tracks[i]);
  if (n < int(r.tracks.size()))
    std::printf("... %zu more (--explain-rows -1 prints all)\n", r.tracks.size() - std::size_t(n));
  std::printf("time: views %.0f ms, scoring %.0f ms, k-means %.0f ms\n", r.views_ms, r.score_ms, r.kmeans_ms);
}

int RunTrain(TrainArgs& a) {
  const cv::Mat img = LoadImageGray(a.image);
  if (!a.quiet) a.opt.progress = [](int d, int t) { Progress("training: view", d, t); };
  Timer t;
  TrainReport report;
  const Model model = TrainNamed(a.image, img, a.opt, &report);
  const double ms = t.ElapsedMs();
  if (a.explain) PrintExplain(report, a.explain_rows);
  SaveModel(model, a.output);
  const auto bytes = std::filesystem::file_size(a.output);
  std::printf("trained %s (%dx%d): %zu locations, %d centres x %d dims, %.0f ms -> %s (%.1f KB)\n", a.image.c_str(),
              img.cols, img.rows, model.locations.size(), model.descriptors.rows, model.params.dims, ms,
              a.output.c_str(), bytes / 1024.0);
  return 0;
}

nlohmann::json MatchJson(const std::string& query, const MatchResult& r) {
  nlohmann::json outline = nullptr;
  if (r.found) {
    outline = nlohmann::json::array();
    for (const auto& p : r.outline) outline.push_back({p.x, p.y});
  }
  return {{"query", query},         {"found", r.found},         {"homography", HomographyJson(r)},
          {"outline", outline},     {"inliers", r.inliers},     {"matches", r.matches.size()},
          {"keypoints", r.keypoints}, {"ratio", r.final_ratio}, {"time_ms", TimingJson(r.time)}};
}

int RunMatch(MatchArgs& a) {
  const Model model = LoadModel(a.model);
  if (a.affine) a.opt.geometry = GeometryModel::kAffine;
  const Matcher matcher(model, a.opt);
  int failures = 0;
  for (std::size_t i = 0; i < a.queries.size(); ++i) {
    const std::string& q = a.queries[i];
    try {
      const cv::Mat frame = LoadImageGray(q);
      const MatchResult r = matcher.Match(frame);
      if (a.json) {
        std::cout << MatchJson(q, r).dump() << std::endl;
      } else if (r.found) {
        std::printf("%s: found, %d inliers of %zu matches, %d keypoints, %.2f ms; outline", q.c_str(), r.inliers,
                    r.matches.size(), r.keypoints, r.time.total());
        for (const auto& p : r.outline) std::printf(" (%.1f, %.1f)", p.x, p.y);
        std::printf("\n");
      } else {
        std::printf("%s: not found (%zu matches, %d keypoints, %.2f ms)\n", q.c_str(), r.matches.size(), r.keypoints,
                    r.time.total());
      }
      if (!a.draw.empty()) SaveImage(IndexedPath(a.draw, int(i), int(a.queries.size())), DrawMatch(LoadImageColor(q), r));
    } catch (const std::exception& e) {
      ++failures;
      std::fprintf(stderr, "mvkp match: %s\n", e.what());
      if (a.json) std::cout << nlohmann::json{{"query", q}, {"error", e.what()}}.dump() << std::endl;
    }
  }
  return failures ? 1 : 0;
}

// pair --method cdikp|sift|orb|akaze|aug-sift|aug-cdikp: extract both images,
// ratio test (0.8 unless --ratio), RANSAC homography; the same JSON as mvkp.
int RunLocalPair(PairArgs& a) {
  Timer total;
  LocalFeatureOptions lo;
  const auto method = LocalFeatureMethod::Create(a.method, lo);
  const cv::Mat img1 = LoadImageGray(a.image1);
  const cv::Mat img2 = LoadImageGray(a.image2);
  const LocalFeatures f1 = method->Extract(img1);
  if (f1.keypoints.empty()) throw Error(ErrorCode::kNoTexture, a.image1 + ": no keypoints found by " + a.method);
  const LocalFeatures f2 = method->Extract(img2);
  if (f2.keypoints.empty()) throw Error(ErrorCode::kNoTexture, a.image2 + ": no keypoints found by " + a.method);
  Timer mt;
  const auto nearest = method->Match(f1, f2);
  const double match_ms = mt.ElapsedMs();
  PairMatchOptions po;
  po.ratio = a.ratio_option && a.ratio_option->count() > 0 ? a.match.ratio : 0.8;
  const PairMatchResult r = MatchPair(f1, f2, nearest, po);
  const double query_ms = f2.detect_ms + f2.describe_ms + f2.augment_ms + match_ms + r.verify_ms;
  const double total_ms = total.ElapsedMs();
  if (a.json) {
    nlohmann::json matches = nlohmann::json::array();
    for (const auto& m : r.matches) matches.push_back({m.object.x, m.object.y, m.query.x, m.query.y, m.distance, m.inlier ? 1 : 0});
    nlohmann::json H = nullptr;
    if (r.found) {
      H = nlohmann::json::array();
      for (int i = 0; i < 3; ++i) H.push_back({r.homography(i, 0), r.homography(i, 1), r.homography(i, 2)});
    }
    const nlohmann::json t = {{"detect", f2.detect_ms}, {"describe", f2.describe_ms}, {"augment", f2.augment_ms},
                              {"search", match_ms},     {"verify", r.verify_ms},     {"query", query_ms},
                              {"total", total_ms}};
    const nlohmann::json out = {{"method", a.method}, {"keypoints1", f1.keypoints.size()}, {"keypoints2", f2.keypoints.size()},
                                {"time_ms", t},       {"homography", H},                 {"matches", matches}};
    std::cout << out.dump() << std::endl;
  } else {
    std::printf("%s -> %s (%s): %s, %d inliers of %zu matches, %zu / %zu keypoints; query %.1f ms, total %.0f ms\n",
                a.image1.c_str(), a.image2.c_str(), a.method.c_str(), r.found ? "found" : "not found", r.inliers,
                r.matches.size(), f1.keypoints.size(), f2.keypoints.size(), query_ms, total_ms);
  }
  if (!a.draw.empty()) {
    MatchResult m;
    m.found = r.found;
    m.homography = r.homography;
    m.inliers = r.inliers;
    for (const auto& c : r.matches) m.matches.push_back({c.object, c.query, c.distance, -1, c.inlier});
    if (r.found) {
      std::vector<cv::Point2f> corners = {{0, 0}, {float(img1.cols - 1), 0}, {float(img1.cols - 1), float(img1.rows - 1)},
                                          {0, float(img1.rows - 1)}}, out;
      cv::perspectiveTransform(corners, out, cv::Mat(r.homography));
      for (int i = 0; i < 4; ++i) m.outline[i] = out[i];
    }
    SaveImage(a.draw, DrawPair(LoadImageColor(a.image1), LoadImageColor(a.image2), m));
  }
  return 0;
}

int RunPair(PairArgs& a) {
  if (a.method != "mvkp") return RunLocalPair(a);
  Timer total;
  const cv::Mat img1 = LoadImageGray(a.image1);
  const cv::Mat img2 = LoadImageGray(a.image2);
  if (a.affine) a.match.geometry = GeometryModel::kAffine;
  const Model model = TrainNamed(a.image1, img1, a.train);
  const Matcher matcher(model, a.match);
  const MatchResult r = matcher.Match(img2);
  const double total_ms = total.ElapsedMs();
  if (a.json) {
    nlohmann::json matches = nlohmann::json::array();
    for (const auto& m : r.matches) matches.push_back({m.object.x, m.object.y, m.query.x, m.query.y, m.distance, m.inlier ? 1 : 0});
    nlohmann::json t = TimingJson(r.time);
    t["train"] = model.params.train_ms;
    t["total"] = total_ms;
    nlohmann::json out = {{"method", "mvkp"}, {"keypoints1", model.locations.size()}, {"keypoints2", r.keypoints},
                          {"time_ms", t}, {"homography", HomographyJson(r)}, {"matches", matches}};
    std::cout << out.dump() << std::endl;
  } else {
    std::printf("%s -> %s: %s, %d inliers of %zu matches; train %.0f ms, query %.2f ms\n", a.image1.c_str(),
                a.image2.c_str(), r.found ? "found" : "not found", r.inliers, r.matches.size(), model.params.train_ms,
                r.time.total());
  }
  if (!a.draw.empty()) SaveImage(a.draw, DrawPair(LoadImageColor(a.image1), LoadImageColor(a.image2), r));
  return 0;
}

}  // namespace

void RegisterTrain(CLI::App& app, int* code) {
  auto a = std::make_shared<TrainArgs>();
  auto* c = app.add_subcommand("train", "Train a planar target from one image");
  c->add_option("IMAGE", a->image, "object image")->required();
  c->add_option("-o,--output", a->output, "model file to write")->required();
  c->add_flag("-q,--quiet", a->quiet, "no progress line");
  c->add_flag("--explain", a->explain, "print every view track's RIFS scores (thesis Table 3.1)");
  c->add_option("--explain-rows", a->explain_rows, "rows --explain prints, best first (-1: all)")->capture_default_str();
  AddTrainOptions(c, &a->opt);
  c->callback([a, code] { *code = RunTrain(*a); });
}

void RegisterMatch(CLI::App& app, int* code) {
  auto a = std::make_shared<MatchArgs>();
  auto* c = app.add_subcommand("match", "Find a trained target in query images");
  c->add_option("MODEL", a->model, "model file from 'mvkp train'")->required();
  c->add_option("QUERY", a->queries, "query images")->required();
  c->add_flag("--json", a->json, "one JSON object per line, per query");
  c->add_option("--draw", a->draw, "write the annotated frame here (-N suffix for several queries)");
  AddMatchOptions(c, &a->opt, &a->affine);
  c->callback([a, code] { *code = RunMatch(*a); });
}

void RegisterPair(CLI::App& app, int* code) {
  auto a = std::make_shared<PairArgs>();
  auto* c = app.add_subcommand("pair", "Train on IMG1, find it in IMG2 (correspondence JSON with --json)");
  c->add_option("IMG1", a->image1, "object image")->required();
  c->add_option("IMG2", a->image2, "query image")->required();
  c->add_flag("--json", a->json, "print the correspondence JSON");
  c->add_option("--draw", a->draw, "write a side-by-side drawing here");
  std::vector<std::string> methods = {"mvkp"};
  for (const auto& m : LocalFeatureMethodNames()) methods.push_back(m);
  c->add_option("--method", a->method,
                "mvkp (train on IMG1, default) | cdikp | sift | orb | akaze | aug-sift | aug-cdikp "
                "(extract both, ratio test 0.8 unless --ratio, RANSAC)")
      ->check(CLI::IsMember(methods))
      ->capture_default_str();
  AddTrainOptions(c, &a->train);
  AddMatchOptions(c, &a->match, &a->affine);
  a->ratio_option = c->get_option("--ratio");
  c->callback([a, code] { *code = RunPair(*a); });
}

}  // namespace mvkp::cli
