// mvkp recognize: which targets of a database are in each query image.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/recognize/recognizer.h"
#include "output.h"
#include "pose_cli.h"

namespace mvkp::cli {
namespace {

struct RecognizeArgs {
  std::string db;
  std::vector<std::string> queries;
  bool json = false;
  bool affine = false;
  std::string draw;
  RecognizerOptions opt;
  PoseSupport pose;  // --camera, --width-m
};

cv::Mat DrawRecognition(const cv::Mat& frame_bgr, const RecognitionResult& r,
                        const std::map<std::string, std::string>& titles) {
  cv::Mat img = frame_bgr.clone();
  for (const auto& f : r.found) {
    std::vector<cv::Point> poly;
    for (const auto& p : f.outline) poly.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
    cv::polylines(img, poly, true, cv::Scalar(0, 255, 0), 3, cv::LINE_AA);
    const std::string t = titles.at(f.id).empty() ? f.id : titles.at(f.id);
    const std::string label = t + " (" + std::to_string(f.inliers) + ")";
    cv::Point at = poly[0];
    for (const auto& p : poly)
      if (p.y < at.y || (p.y == at.y && p.x < at.x)) at = p;
    at.x = std::clamp(at.x, 5, std::max(5, img.cols - 200));
    at.y = std::clamp(at.y - 8, 20, std::max(20, img.rows - 5));
    cv::putText(img, label, at, cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 0), 4, cv::LINE_AA);
    cv::putText(img, label, at, cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 255, 0), 2, cv::LINE_AA);
  }
  if (r.found.empty())
    cv::putText(img, "no target", {10, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 255), 2, cv::LINE_AA);
  return img;
}

int RunRecognize(RecognizeArgs& a) {
  if (a.affine) a.opt.match.geometry = GeometryModel::kAffine;
  a.opt.Check();
  a.pose.Load();  // a bad --camera file fails before any work
  Timer tl;
  const TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadOnly);
  Require(store.Count() > 0, ErrorCode::kInvalidArgument, a.db + ": DB has no targets");
  Recognizer rec(a.opt);
  std::map<std::string, std::string> titles;
  std::vector<SkippedTarget> skipped;
  const std::size_t encoded = LoadTargets(
      store, rec, a.db,
      [&](const TargetInfo& info, int width, int height) {
        a.pose.AddTarget(info.id, info.meta, width, height, a.db);
        titles[info.id] = info.title;
      },
      &skipped);
  // A damaged row costs its own target only.
  for (const auto& s : skipped) std::fprintf(stderr, "warning: skipped a target: %s\n", s.error.c_str());
  Require(rec.size() > 0, ErrorCode::kInvalidArgument, a.db + ": DB has no readable targets");
  rec.ShrinkToFit();
  const std::size_t bytes = rec.memory_bytes();  // also builds the index
  const double load_ms = tl.ElapsedMs();
  // Load time: a text line first, or fields of every JSON line (stderr stays for errors only).
  if (!a.json)
    std::printf("loaded %s from %s in %.1f ms (%.2f MB in memory%s)\n", Count(rec.size(), "target").c_str(), a.db.c_str(), load_ms,
                bytes / 1048576.0,
                a.opt.search == RecognizerSearch::kWords
                    ? (", " + std::to_string(encoded) + " from stored word encodings").c_str()
                    : "");

  int failures = 0;
  for (std::size_t i = 0; i < a.queries.size(); ++i) {
    const std::string& q = a.queries[i];
    try {
      const cv::Mat frame = LoadImageGray(q);
      if (a.pose.enabled()) a.pose.Camera(frame.size(), q);  // another aspect ratio: an error for this query
      const RecognitionResult r = rec.Recognize(frame);
      std::vector<std::optional<Pose>> poses;
      for (const auto& f : r.found) poses.push_back(a.pose.Estimate(f, frame.size(), q));
      if (a.json) {
        nlohmann::json found = nlohmann::json::array();
        for (std::size_t k = 0; k < r.found.size(); ++k) {
          found.push_back(RecognitionJson(r.found[k], titles[r.found[k].id]));
          if (poses[k]) found.back()["pose"] = PoseSupport::Json(*poses[k]);
        }
        const nlohmann::json time = {{"detect", r.detect_ms},
                                     {"describe", r.describe_ms},
                                     {"search", r.search_ms},
                                     {"verify", r.verify_ms},
                                     {"total", r.total_ms()}};
        std::cout << nlohmann::json{{"query", q}, {"found", found}, {"keypoints", r.keypoints},
                                     {"time_ms", time}, {"targets", rec.size()}, {"load_ms", load_ms}}.dump()
                  << std::endl;
      } else if (r.found.empty()) {
        std::printf("%s: no target (%d matches, %d keypoints, %.2f ms)\n", q.c_str(), r.matches, r.keypoints,
                    r.total_ms());
      } else {
        std::printf("%s:", q.c_str());
        for (std::size_t k = 0; k < r.found.size(); ++k) {
          const auto& f = r.found[k];
          std::printf("%s %s", k ? "," : "", f.id.c_str());
          if (!titles[f.id].empty()) std::printf(" \"%s\"", titles[f.id].c_str());
          std::printf(" (%d inliers of %d votes", f.inliers, f.votes);
          if (poses[k]) std::printf(", distance %.2f m", poses[k]->distance);
          std::printf(")");
        }
        std::printf("; %d keypoints, %.2f ms\n", r.keypoints, r.total_ms());
      }
      if (!a.draw.empty()) {
        cv::Mat img = DrawRecognition(LoadImageColor(q), r, titles);
        for (std::size_t k = 0; k < r.found.size(); ++k)
          if (poses[k]) a.pose.DrawAxes(img, r.found[k].id, *poses[k], frame.size(), q);
        SaveImage(IndexedPath(a.draw, int(i), int(a.queries.size())), img);
      }
    } catch (const std::exception& e) {
      ++failures;
      std::fprintf(stderr, "mvkp recognize: %s\n", e.what());
      if (a.json) std::cout << nlohmann::json{{"query", q}, {"error", e.what()}}.dump() << std::endl;
    }
  }
  return failures ? 1 : 0;
}

}  // namespace

void RegisterRecognize(CLI::App& app, int* code) {
  auto a = std::make_shared<RecognizeArgs>();
  auto* c = app.add_subcommand("recognize", "Recognise which targets of a database are in query images");
  c->add_option("DB", a->db, "target database from 'mvkp db'")->required();
  c->add_option("QUERY", a->queries, "query images")->required();
  c->add_flag("--json", a->json, "one JSON object per line, per query");
  c->add_option("--draw", a->draw,
                "write the frame with each found outline, title and pose axes here (-N suffix for several queries)");
  a->pose.AddOptions(c);
  MatchOptions& m = a->opt.match;
  c->add_option("--ratio", m.ratio, "distance-ratio threshold d1/d2")->capture_default_str();
  c->add_option("--dynamic-goal", m.dynamic_goal,
                "per-target dynamic ratio (thesis 6.3.1): keep each target's best matches up to --ratio-max until it "
                "has this many (those under --ratio-min always count); 0: the fixed --ratio")
      ->capture_default_str();
  c->add_option("--ratio-min", m.ratio_min, "dynamic ratio: matches under it always count")->capture_default_str();
  c->add_option("--ratio-max", m.ratio_max, "dynamic ratio: no match above it counts")->capture_default_str();
  c->add_option("--max-points", m.max_points, "strongest query points (--search words: 600 unless given)")
      ->capture_default_str();
  c->add_option("--half-res-points", m.half_res_points, "extra points from half resolution when nothing is found (0: off)")
      ->capture_default_str();
  c->add_option("--ransac-threshold", m.ransac_threshold, "inlier reprojection error, pixels")->capture_default_str();
  c->add_flag("--affine", a->affine, "fit an affine transform instead of a homography");
  c->add_option("--index", m.index, "descriptor search: exact (FFVA) | approx | brute")
      ->check(CLI::IsMember({"exact", "approx", "brute"}))
      ->capture_default_str();
  const std::map<std::string, RobustMethod> methods = {{"ransac", RobustMethod::kRansac}, {"fast", RobustMethod::kFast},
                                                       {"accurate", RobustMethod::kAccurate}, {"magsac", RobustMethod::kMagsac}};
  c->add_option("--robust", m.robust, "robust estimator: ransac | fast | accurate | magsac")
      ->transform(CLI::CheckedTransformer(methods, CLI::ignore_case))
      ->default_str("accurate");
  c->add_option("--max-candidates", a->opt.max_candidates, "targets verified per frame, most votes first")->capture_default_str();
  c->add_option("--min-votes", a->opt.min_votes, "ratio-test matches a target needs to be verified")->capture_default_str();
  c->add_option("--min-inliers", a->opt.min_inliers, "RANSAC inliers to accept a target")->capture_default_str();
  const std::map<std::string, RecognizerSearch> searches = {{"exact", RecognizerSearch::kExact},
                                                            {"words", RecognizerSearch::kWords}};
  c->add_option("--search", a->opt.search,
                "exact: all centres in one FFVA index (best recall, ~700 KB/target); words: inverted file of visual "
                "words with Hamming signatures (~7 KB/target, for thousands of targets)")
      ->transform(CLI::CheckedTransformer(searches, CLI::ignore_case))
      ->default_str("exact");
  c->add_option("--query-words", a->opt.query_words, "words: nearest words looked up per query descriptor")
      ->capture_default_str();
  c->add_option("--max-hamming", a->opt.max_hamming, "words: signature bits (of 20) that may differ")->capture_default_str();
  c->add_option("--probe-words", a->opt.probe_words,
                "exact: 0 compares with every centre; N only with those in the query's N nearest words (faster, approximate)")
      ->capture_default_str();
  c->add_option("--max-locations", a->opt.max_locations, "words: locations stored per target (<= 256)")
      ->capture_default_str();
  c->add_option("--words-per-location", a->opt.words_per_location, "words: postings per location")->capture_default_str();
  c->callback([a, code, c] {
    // The word search has its own query budget unless one is given.
    if (a->opt.search == RecognizerSearch::kWords && c->count("--max-points") == 0)
      a->opt.match.max_points = RecognizerOptions::Words().match.max_points;
    *code = RunRecognize(*a);
  });
}

}  // namespace mvkp::cli
