// The C++ side of bench_overhead.py: load a model and frames as `mvkp match`
// does (LoadModel, LoadImageGray), then time Matcher::Match per frame,
// single-threaded, `rounds` times over the frames. Prints one JSON line:
// {"per_frame_ms": [...median over rounds per frame...], "mean_ms": (their mean),
//  "mean_min_ms": (mean over frames of the fastest round), "outside_stages_ms": (median
//  wall time per call not covered by MatchResult::time, i.e. the call's own cost), "found": N}.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/core/image_io.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: mvkp_match_bench ROUNDS MODEL FRAME...\n");
    return 2;
  }
  cv::setNumThreads(1);
  const int rounds = std::max(1, std::atoi(argv[1]));
  const mvkp::Model model = mvkp::LoadModel(argv[2]);
  const mvkp::Matcher matcher(model);
  std::vector<cv::Mat> frames;
  for (int i = 3; i < argc; ++i) frames.push_back(mvkp::LoadImageGray(argv[i]));
  std::vector<std::vector<double>> ms(frames.size());
  std::vector<double> outside;  // wall time minus the matcher's own stage timings
  int found = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) matcher.Match(frames[i]);  // warm-up
  for (int r = 0; r < rounds; ++r)
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      const mvkp::MatchResult res = matcher.Match(frames[i]);
      const auto t1 = std::chrono::steady_clock::now();
      ms[i].push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      outside.push_back(ms[i].back() - res.time.total());
      if (r == 0) found += res.found;
    }
  std::printf("{\"per_frame_ms\": [");
  double sum = 0, sum_min = 0;
  for (std::size_t i = 0; i < ms.size(); ++i) {
    std::sort(ms[i].begin(), ms[i].end());
    const double med = ms[i][ms[i].size() / 2];
    sum += med;
    sum_min += ms[i][0];
    std::printf("%s%.4f", i ? ", " : "", med);
  }
  std::sort(outside.begin(), outside.end());
  std::printf("], \"mean_ms\": %.4f, \"mean_min_ms\": %.4f, \"outside_stages_ms\": %.4f, \"found\": %d}\n",
              sum / double(ms.size()), sum_min / double(ms.size()), outside[outside.size() / 2], found);
  return 0;
}
