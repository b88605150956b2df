// mvkp eval oxford: the Mikolajczyk–Schmid protocol (thesis §4.3.1) on folders
// laid out like the Oxford affine sequences (img1..img6 + H1to2p..H1to6p) or
// holding a `mvkp synth` manifest. For every method and pair: matches and
// correct matches over ten ratio thresholds (precision, recall), the
// homography corner error at one ratio, and per-keypoint detection,
// description and augmentation times, all in the same single-thread run.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>

#include "baselines.h"
#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/local/local_features.h"
#include "mvkp/local/pair_match.h"
#include "mvkp/match/matcher.h"
#include "output.h"
#include "svg_plot.h"

namespace mvkp::cli {
namespace {

namespace fs = std::filesystem;

struct OxfordArgs {
  std::vector<std::string> dirs;
  std::vector<std::string> methods = {"sift", "cdikp", "aug-sift", "aug-cdikp", "orb", "akaze"};
  std::string out = "out/eval-oxford";
  double ratio = 0.8;  // for the homography and the matches-at-a-ratio figure
  double eps = 3.0;    // a match is correct within this many pixels of the truth
  int max_features = 0;
};

// Pairs of one folder: its manifest.txt, or img1 -> img2..img6 with H1toNp.
std::vector<ManifestPair> PairsOf(const std::string& dir) {
  Require(fs::is_directory(dir), ErrorCode::kIo, dir + ": not a folder");
  const fs::path d(dir);
  if (fs::exists(d / "manifest.txt")) {
    auto pairs = ReadManifest((d / "manifest.txt").string());
    for (const auto& p : pairs)
      Require(p.h != "none", ErrorCode::kInvalidArgument,
              (d / "manifest.txt").string() + ": every pair needs a homography (found 'none')");
    Require(!pairs.empty(), ErrorCode::kInvalidArgument, (d / "manifest.txt").string() + ": no pairs");
    return pairs;
  }
  auto image = [&](int n) -> std::string {
    for (const char* ext : {".ppm", ".pgm", ".png", ".jpg", ".jpeg"}) {
      const fs::path p = d / ("img" + std::to_string(n) + ext);
      if (fs::exists(p)) return p.string();
    }
    return "";
  };
  const std::string img1 = image(1);
  Require(!img1.empty(), ErrorCode::kIo, dir + ": no img1.ppm (or .pgm/.png/.jpg) and no manifest.txt");
  std::vector<ManifestPair> pairs;
  for (int n = 2; n <= 6; ++n) {
    const std::string img = image(n);
    if (img.empty()) continue;
    const fs::path h = d / ("H1to" + std::to_string(n) + "p");
    Require(fs::exists(h), ErrorCode::kIo, h.string() + ": missing homography for " + img);
    pairs.push_back({img1, img, h.string(), d.filename().string()});
  }
  Require(!pairs.empty(), ErrorCode::kIo, dir + ": img1 but no img2..img6");
  return pairs;
}

struct PairRow {
  std::string method, set, pair;
  int keypoints1 = 0, keypoints2 = 0, correspondences = 0;
  std::vector<RatioPoint> sweep;
  int matches = 0, inliers = 0;  // at args.ratio
  double corner_err = INFINITY;
};

struct MethodStats {
  double detect_ms = 0, describe_ms = 0, augment_ms = 0;
  long keypoints = 0;
  int images = 0, bytes = 0;
};

std::string Csv(const std::string& s) { return s.find(',') == std::string::npos ? s : "\"" + s + "\""; }

int RunOxford(OxfordArgs& a) {
  Require(!a.dirs.empty(), ErrorCode::kInvalidArgument, "eval oxford: give at least one folder");
  Require(a.ratio > 0 && a.ratio <= 1, ErrorCode::kInvalidArgument, "--ratio must be in (0, 1]");
  Require(a.eps > 0, ErrorCode::kInvalidArgument, "--eps must be > 0");
  std::vector<ManifestPair> pairs;
  for (const auto& d : a.dirs) {
    auto p = PairsOf(d);
    pairs.insert(pairs.end(), p.begin(), p.end());
  }
  for (const auto& p : pairs) ReadHomography(p.h);  // malformed files fail before any work
  LocalFeatureOptions lo;
  lo.max_features = a.max_features;
  std::vector<std::unique_ptr<LocalFeatureMethod>> methods;
  for (const auto& m : a.methods) methods.push_back(LocalFeatureMethod::Create(m, lo));
  const auto ratios = DefaultRatioSweep();

  std::map<std::string, cv::Mat> images;
  auto load = [&](const std::string& path) -> const cv::Mat& {
    auto it = images.find(path);
    if (it == images.end()) it = images.emplace(path, LoadImageGray(path)).first;
    return it->second;
  };
  std::vector<PairRow> rows;
  std::map<std::string, MethodStats> stats;
  int done = 0;
  const int total = int(methods.size() * pairs.size());
  for (const auto& method : methods) {
    std::map<std::string, LocalFeatures> feats;
    auto features = [&](const std::string& path) -> const LocalFeatures& {
      auto it = feats.find(path);
      if (it != feats.end()) return it->second;
      LocalFeatures f = method->Extract(load(path));
      if (f.keypoints.empty()) throw Error(ErrorCode::kNoTexture, path + ": no keypoints found by " + method->name());
      MethodStats& s = stats[method->name()];
      s.detect_ms += f.detect_ms;
      s.describe_ms += f.describe_ms;
      s.augment_ms += f.augment_ms;
      s.keypoints += long(f.keypoints.size());
      s.images += 1;
      s.bytes = method->descriptor_bytes();
      return feats.emplace(path, std::move(f)).first->second;
    };
    for (const auto& p : pairs) {
      const LocalFeatures& f1 = features(p.img1);
      const LocalFeatures& f2 = features(p.img2);
      const cv::Matx33d H = ReadHomography(p.h);
      const auto nearest = method->Match(f1, f2);
      PairRow row;
      row.method = method->name();
      row.set = p.set;
      row.pair = fs::path(p.img1).stem().string() + "-" + fs::path(p.img2).stem().string();
      row.keypoints1 = int(f1.keypoints.size());
      row.keypoints2 = int(f2.keypoints.size());
      const PairEvaluation e = EvaluatePair(f1, f2, nearest, H, load(p.img2).size(), ratios, a.eps);
      row.correspondences = e.correspondences;
      row.sweep = e.sweep;
      PairMatchOptions po;
      po.ratio = a.ratio;
      const PairMatchResult r = MatchPair(f1, f2, nearest, po);
      row.matches = int(r.matches.size());
      row.inliers = r.inliers;
      if (r.found) row.corner_err = MeanCornerError(r.homography, H, load(p.img1).size());
      rows.push_back(row);
      Progress("eval oxford: pair", ++done, total);
    }
  }

  std::error_code ec;
  fs::create_directories(a.out, ec);
  Require(fs::is_directory(a.out), ErrorCode::kIo, a.out + ": cannot create report folder");
  const fs::path out(a.out);
  // Per pair and ratio.
  {
    std::ofstream f(out / "pairs.csv");
    f << "method,set,pair,ratio,matches,correct,correspondences,precision,recall\n";
    for (const auto& r : rows)
      for (const auto& s : r.sweep)
        f << r.method << "," << Csv(r.set) << "," << r.pair << "," << s.ratio << "," << s.matches << "," << s.correct << ","
          << r.correspondences << "," << (s.matches ? double(s.correct) / s.matches : 0.0) << ","
          << (r.correspondences ? double(s.correct) / r.correspondences : 0.0) << "\n";
    Require(bool(f), ErrorCode::kIo, (out / "pairs.csv").string() + ": cannot write");
  }
  {
    std::ofstream f(out / "homography.csv");
    f << "method,set,pair,keypoints1,keypoints2,matches,inliers,corner_error\n";
    for (const auto& r : rows)
      f << r.method << "," << Csv(r.set) << "," << r.pair << "," << r.keypoints1 << "," << r.keypoints2 << "," << r.matches
        << "," << r.inliers << "," << (std::isfinite(r.corner_err) ? std::to_string(r.corner_err) : "") << "\n";
  }
  // Summary per method.
  nlohmann::json summary = nlohmann::json::object();
  std::printf("ratio %.2f, correct within %.1f px; %zu pairs\n", a.ratio, a.eps, pairs.size());
  std::printf("%-10s %6s %7s %7s %9s %9s %8s %6s %9s %9s %9s\n", "method", "pairs", "ok@10", "ok@5", "correct", "matches",
              "prec", "bytes", "det us/kp", "desc us/kp", "aug us/kp");
  int ri = -1;  // sweep index of the reporting ratio (or nearest)
  for (int i = 0; i < int(ratios.size()); ++i)
    if (ri < 0 || std::abs(ratios[i] - a.ratio) < std::abs(ratios[ri] - a.ratio)) ri = i;
  for (const auto& m : methods) {
    int n = 0, ok10 = 0, ok5 = 0;
    double correct = 0, matches = 0;
    for (const auto& r : rows)
      if (r.method == m->name()) {
        ++n;
        ok10 += r.corner_err < 10;
        ok5 += r.corner_err < 5;
        correct += r.sweep[ri].correct;
        matches += r.sweep[ri].matches;
      }
    const MethodStats& s = stats[m->name()];
    const double kp = std::max(1L, s.keypoints);
    const double det = 1000 * s.detect_ms / kp, desc = 1000 * s.describe_ms / kp, aug = 1000 * s.augment_ms / kp;
    std::printf("%-10s %6d %7.3f %7.3f %9.1f %9.1f %8.3f %6d %9.2f %9.2f %9.2f\n", m->name().c_str(), n,
                double(ok10) / n, double(ok5) / n, correct / n, matches / n, matches ? correct / matches : 0.0, s.bytes,
                det, desc, aug);
    summary[m->name()] = {{"pairs", n},
                          {"ok10", double(ok10) / n},
                          {"ok5", double(ok5) / n},
                          {"correct_at_ratio", correct / n},
                          {"matches_at_ratio", matches / n},
                          {"precision_at_ratio", matches ? correct / matches : 0.0},
                          {"descriptor_bytes", s.bytes},
                          {"keypoints_per_image", s.keypoints / double(std::max(1, s.images))},
                          {"detect_us_per_keypoint", det},
                          {"describe_us_per_keypoint", desc},
                          {"augment_us_per_keypoint", aug},
                          {"augment_share_of_extraction",
                           s.detect_ms + s.describe_ms > 0 ? s.augment_ms / (s.detect_ms + s.describe_ms) : 0.0}};
  }
  {
    std::ofstream f(out / "summary.csv");
    f << "method,pairs,ok10,ok5,correct_at_ratio,matches_at_ratio,precision_at_ratio,descriptor_bytes,"
         "detect_us_per_keypoint,describe_us_per_keypoint,augment_us_per_keypoint,augment_share_of_extraction\n";
    for (const auto& m : methods) {
      const auto& j = summary[m->name()];
      f << m->name() << "," << j["pairs"] << "," << j["ok10"] << "," << j["ok5"] << "," << j["correct_at_ratio"] << ","
        << j["matches_at_ratio"] << "," << j["precision_at_ratio"] << "," << j["descriptor_bytes"] << ","
        << j["detect_us_per_keypoint"] << "," << j["describe_us_per_keypoint"] << "," << j["augment_us_per_keypoint"]
        << "," << j["augment_share_of_extraction"] << "\n";
    }
  }
  nlohmann::json jrows = nlohmann::json::array();
  for (const auto& r : rows) {
    nlohmann::json sw = nlohmann::json::array();
    for (const auto& s : r.sweep) sw.push_back({{"ratio", s.ratio}, {"matches", s.matches}, {"correct", s.correct}});
    jrows.push_back({{"method", r.method},
                     {"set", r.set},
                     {"pair", r.pair},
                     {"keypoints1", r.keypoints1},
                     {"keypoints2", r.keypoints2},
                     {"correspondences", r.correspondences},
                     {"sweep", sw},
                     {"matches", r.matches},
                     {"inliers", r.inliers},
                     {"corner_error", std::isfinite(r.corner_err) ? nlohmann::json(r.corner_err) : nlohmann::json(nullptr)}});
  }
  std::ofstream(out / "summary.json") << nlohmann::json{{"ratio", a.ratio}, {"eps_px", a.eps}, {"summary", summary},
                                                        {"rows", jrows}}
                                             .dump(1)
                                      << "\n";

  // Plots: recall against 1 - precision per set (thesis Fig. 4.5), pooled
  // over the set's pairs; correct matches at the ratio per pair (Fig. 4.6).
  std::vector<std::string> sets;
  for (const auto& p : pairs)
    if (std::find(sets.begin(), sets.end(), p.set) == sets.end()) sets.push_back(p.set);
  std::vector<std::string> written;
  for (const auto& set : sets) {
    LineChart c;
    c.title = "recall vs 1 - precision: " + set;
    c.subtitle = "ratio thresholds 0.50..0.95, pooled over the pairs; correct within " + std::to_string(int(a.eps)) + " px";
    c.xlabel = "1 - precision";
    c.ylabel = "recall";
    c.xmin = 0;
    c.xmax = 1;
    c.ymin = 0;
    for (const auto& m : methods) {
      Series s;
      s.name = m->name();
      for (int i = 0; i < int(ratios.size()); ++i) {
        double corr = 0, mat = 0, cor = 0;
        for (const auto& r : rows)
          if (r.method == m->name() && r.set == set) {
            corr += r.sweep[i].correct;
            mat += r.sweep[i].matches;
            cor += r.correspondences;
          }
        if (mat > 0 && cor > 0) {
          s.x.push_back(1 - corr / mat);
          s.y.push_back(corr / cor);
        }
      }
      c.series.push_back(s);
    }
    const std::string path = (out / ("recall_" + set + ".svg")).string();
    WriteTextFile(path, RenderLineChart(c));
    written.push_back(path);
  }
  BarChart b;
  b.title = "correct matches at ratio " + std::to_string(a.ratio).substr(0, 4);
  b.subtitle = "per image pair; correct within " + std::to_string(int(a.eps)) + " px of the true homography";
  b.ylabel = "correct matches";
  for (const auto& m : methods) b.series.push_back(m->name());
  for (const auto& p : pairs) {
    BarGroup g;
    g.label = p.set + " " + fs::path(p.img1).stem().string() + "-" + fs::path(p.img2).stem().string();
    for (const auto& m : methods)
      for (const auto& r : rows)
        if (r.method == m->name() && r.set == p.set && r.pair == fs::path(p.img1).stem().string() + "-" + fs::path(p.img2).stem().string())
          g.values.push_back(r.sweep[ri].correct);
    b.groups.push_back(g);
  }
  WriteTextFile((out / "matches.svg").string(), RenderBarChart(b));
  written.push_back((out / "matches.svg").string());
  std::printf("report: %s/{summary.csv,summary.json,pairs.csv,homography.csv}", a.out.c_str());
  for (const auto& w : written) std::printf(" %s", w.c_str());
  std::printf("\n");
  return 0;
}

}  // namespace

void RegisterEvalOxford(CLI::App* eval, int* code) {
  auto a = std::make_shared<OxfordArgs>();
  auto* c = eval->add_subcommand(
      "oxford", "Mikolajczyk-Schmid protocol on Oxford-style folders (img1..6 + H1toNp) or mvkp synth folders");
  c->add_option("DIR", a->dirs, "sequence folders (or folders holding a manifest.txt)")->required();
  std::vector<std::string> names = LocalFeatureMethodNames();
  c->add_option("--methods", a->methods, "methods to compare")->delimiter(',')->check(CLI::IsMember(names))->capture_default_str();
  c->add_option("-o,--output", a->out, "report folder (CSV, JSON, SVG)")->capture_default_str();
  c->add_option("--ratio", a->ratio, "ratio for the homography and the matches figure")->capture_default_str();
  c->add_option("--eps", a->eps, "a match is correct within this many pixels")->capture_default_str();
  c->add_option("--max-features", a->max_features, "keypoint cap (0: all for SIFT/CDIKP)")->capture_default_str();
  c->callback([a, code] { *code = RunOxford(*a); });
}

}  // namespace mvkp::cli
