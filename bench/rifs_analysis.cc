// mvkp_rifs_analysis: which view tracks actually produce correct matches?
// For each target set (a `mvkp synth` directory: target.png, view_*.png,
// H_*.txt) it trains once keeping every eligible track, matches every view,
// and writes per track its RIFS statistics (under each choice of statistics
// views) and per view the correct matches of each track. scripts/rifs_ranking.py
// then compares rankings offline: a ranking is good when its top-K tracks
// hold enough correct matches in as many views as possible.
//   mvkp_rifs_analysis OUT.csv SET_DIR... [--views N --clusters K --seed S]
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/calib3d.hpp>

#include "mvkp/core/image_io.h"
#include "mvkp/match/matcher.h"
#include "mvkp/train/trainer.h"

namespace fs = std::filesystem;
using namespace mvkp;

int main(int argc, char** argv) {
  CLI::App app{"RIFS analysis: per-track statistics and per-view correct matches"};
  std::string out;
  std::vector<std::string> sets;
  int views = 50, clusters = 10;
  std::uint64_t seed = 1;
  app.add_option("OUT", out)->required();
  app.add_option("SET", sets)->required();
  app.add_option("--views", views);
  app.add_option("--clusters", clusters);
  app.add_option("--seed", seed);
  CLI11_PARSE(app, argc, argv);
  std::ofstream tracks(out + ".tracks.csv"), hits(out + ".hits.csv");
  tracks << "target,x,y,ss,general,ds_all,vs_all,ds_gen,vs_gen,ds_rot,vs_rot,nn_model\n";
  hits << "target,view,x,y,correct,wrong\n";
  for (const auto& dir : sets) {
    const std::string name = fs::path(dir).filename().string();
    const cv::Mat target = LoadImageGray(dir + "/target.png");
    TrainOptions o;
    o.views = views;
    o.clusters = clusters;
    o.seed = seed;
    o.keep_fraction = 1.0;
    o.select = Selection::kRifs;
    std::map<std::pair<int, int>, std::vector<double>> stats;  // (x, y) -> columns
    Model model;
    using SV = TrainOptions::StatsViews;
    int variant = 0;
    for (SV sv : {SV::kAll, SV::kGeneral, SV::kRotation}) {
      o.stats_views = sv;
      TrainReport r;
      Model m = Train(target, o, &r);
      for (const auto& t : r.tracks) {
        if (t.rank < 0) continue;
        auto& v = stats[{int(t.x), int(t.y)}];
        if (variant == 0) v = {double(t.score.ss), double(t.general)};
        if (int(v.size()) == 2 + 2 * variant) {
          v.push_back(t.score.ds);
          v.push_back(t.score.vs);
        }
      }
      if (sv == SV::kRotation) model = std::move(m);
      ++variant;
    }
    // Nearest other location (mean of its centres) in the model, per location.
    const int nl = int(model.locations.size()), d = model.descriptors.cols;
    cv::Mat means = cv::Mat::zeros(nl, d, CV_64F);
    std::vector<int> cnt(nl, 0);
    for (int i = 0; i < model.descriptors.rows; ++i) {
      for (int l = 0; l < d; ++l) means.at<double>(model.labels[i], l) += model.descriptors.at<float>(i, l);
      ++cnt[model.labels[i]];
    }
    for (int j = 0; j < nl; ++j) means.row(j) /= std::max(1, cnt[j]);
    std::vector<double> nn(nl, 1e18);
    for (int a = 0; a < nl; ++a)
      for (int b = a + 1; b < nl; ++b) {
        const double dist = cv::norm(means.row(a), means.row(b));
        nn[a] = std::min(nn[a], dist);
        nn[b] = std::min(nn[b], dist);
      }
    // Locations are reported in input pixels; join by rounding to the candidate grid.
    std::map<std::pair<int, int>, double> nn_at;
    for (int j = 0; j < nl; ++j) nn_at[{int(std::lround(model.locations[j].x)), int(std::lround(model.locations[j].y))}] = nn[j];
    for (const auto& [xy, v] : stats) {
      if (v.size() != 8) continue;
      double nnv = -1;
      for (int dy = -2; dy <= 2 && nnv < 0; ++dy)
        for (int dx = -2; dx <= 2 && nnv < 0; ++dx) {
          auto it = nn_at.find({xy.first + dx, xy.second + dy});
          if (it != nn_at.end()) nnv = it->second;
        }
      tracks << name << "," << xy.first << "," << xy.second;
      for (double x : v) tracks << "," << x;
      tracks << "," << nnv << "\n";
    }
    const Matcher matcher(model, MatchOptions{});
    for (int i = 0;; ++i) {
      char vn[64], hn[64];
      std::snprintf(vn, sizeof vn, "/view_%04d.png", i);
      std::snprintf(hn, sizeof hn, "/H_%04d.txt", i);
      if (!fs::exists(dir + vn)) break;
      const cv::Mat view = LoadImageGray(dir + vn);
      cv::Matx33d H;
      std::ifstream hf(dir + hn);
      for (int k = 0; k < 9; ++k) hf >> H.val[k];
      const MatchResult r = matcher.Match(view);
      std::map<int, std::pair<int, int>> per;
      for (const auto& c : r.matches) {
        const cv::Vec3d p = H * cv::Vec3d(c.object.x, c.object.y, 1);
        const bool ok = std::hypot(p[0] / p[2] - c.query.x, p[1] / p[2] - c.query.y) < 3.0;
        auto& e = per[c.location];
        (ok ? e.first : e.second)++;
      }
      for (const auto& [loc, e] : per)
        hits << name << "," << i << "," << std::lround(model.locations[loc].x) << "," << std::lround(model.locations[loc].y)
             << "," << e.first << "," << e.second << "\n";
    }
    std::fprintf(stderr, "%s: %d locations\n", name.c_str(), nl);
  }
  return 0;
}
