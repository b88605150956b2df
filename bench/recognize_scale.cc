// mvkp_recognize_scale: recognition speed and memory against the number of
// targets (issue 6, "speed at scale").
//
// N distinct targets are generated deterministically from --seed: a procedural
// canvas (low-frequency noise, random blobs, rectangles, lines, polylines and
// text) with a randomly scaled, rotated and flipped crop of one of the sample
// photos pasted into it, then an overlay of a few more shapes, at most 320 px
// on the longest side. The holdout photo (--holdout, default fruits) never
// appears in a target. All targets of the largest size are trained once; the
// recogniser for each size N holds the first N of them.
//
// Per size: --frames 640x480 frames, 80 % with one random target rendered by
// MakeSceneView (known id and homography), 20 % with no target (alternately a
// scene of a crop of the holdout photo and a scene of a fresh procedural image
// that is not a target). Recognition runs single threaded
// (cv::setNumThreads(1)). Reported: median and mean ms per frame (wall clock
// around Recognize, and per stage), recall@top1 (found[0] is the right id with
// mean corner error < 10 px), frames with a wrong id found, detections on
// no-target frames, memory_bytes() and serialized model bytes per target,
// training ms per target, Add and index-build time.
//
//   mvkp_recognize_scale [--sizes 10,100,1000] [--frames 50] [--seed 1]
//                        [--views 50] [--locations 200] [--json OUT]
//                        [--cache DIR] [--large]
// Sizes above 1000 need --large (training 10000 targets takes hours).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/trainer.h"

#ifndef MVKP_SOURCE_DIR
#define MVKP_SOURCE_DIR "."
#endif

namespace fs = std::filesystem;
using namespace mvkp;

namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

struct Rng {
  std::mt19937_64 g;
  explicit Rng(std::uint64_t s) : g(s) {}
  double U(double a, double b) { return std::uniform_real_distribution<double>(a, b)(g); }
  int I(int a, int b) { return std::uniform_int_distribution<int>(a, b)(g); }  // inclusive
};

std::uint64_t Mix(std::uint64_t a, std::uint64_t b) {
  std::uint64_t x = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull + (a << 6) + (a >> 2));
  x ^= x >> 31;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 29;
  return x;
}

// A random crop (size in [lo, hi] px before the crop is cut) of a randomly
// scaled, rotated and possibly flipped photo.
cv::Mat PhotoCrop(const cv::Mat& photo, Rng& r, int lo, int hi) {
  const double s = r.U(0.8, 1.8);
  const double angle = r.U(-180, 180);
  const cv::Point2f c(photo.cols / 2.f, photo.rows / 2.f);
  cv::Mat M = cv::getRotationMatrix2D(c, angle, s);
  // Output large enough for the rotated, scaled photo.
  const double diag = std::hypot(photo.cols, photo.rows) * s;
  const int side = int(std::ceil(diag));
  M.at<double>(0, 2) += side / 2.0 - c.x;
  M.at<double>(1, 2) += side / 2.0 - c.y;
  cv::Mat big;
  cv::warpAffine(photo, big, M, cv::Size(side, side), cv::INTER_LINEAR, cv::BORDER_REFLECT101);
  if (r.I(0, 1)) cv::flip(big, big, 1);
  // Stay inside the inscribed region of the rotated photo (side/sqrt(2) centred, roughly).
  const int inner = std::max(32, int(std::min(photo.cols, photo.rows) * s * 0.7));
  const int w = std::min(inner, r.I(lo, hi)), h = std::min(inner, r.I(lo, hi));
  const int x0 = (side - inner) / 2 + r.I(0, inner - w), y0 = (side - inner) / 2 + r.I(0, inner - h);
  return big(cv::Rect(x0, y0, w, h)).clone();
}

void DrawShapes(cv::Mat& img, Rng& r, int count) {
  static const char kChars[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789&%#@";
  static const int kFonts[] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX, cv::FONT_HERSHEY_COMPLEX,
                               cv::FONT_HERSHEY_TRIPLEX, cv::FONT_HERSHEY_SCRIPT_SIMPLEX, cv::FONT_HERSHEY_PLAIN};
  const int W = img.cols, H = img.rows;
  for (int i = 0; i < count; ++i) {
    const cv::Scalar col(r.U(0, 255));
    const cv::Point c(r.I(0, W - 1), r.I(0, H - 1));
    switch (r.I(0, 5)) {
      case 0:
        cv::circle(img, c, r.I(3, 40), col, r.I(0, 1) ? -1 : r.I(1, 4), cv::LINE_AA);
        break;
      case 1:
        cv::rectangle(img, c, c + cv::Point(r.I(-60, 60), r.I(-60, 60)), col, r.I(0, 1) ? -1 : r.I(1, 4), cv::LINE_AA);
        break;
      case 2:
        cv::line(img, c, c + cv::Point(r.I(-150, 150), r.I(-150, 150)), col, r.I(1, 5), cv::LINE_AA);
        break;
      case 3:
        cv::ellipse(img, c, cv::Size(r.I(4, 50), r.I(3, 30)), r.U(0, 180), 0, 360, col, r.I(0, 1) ? -1 : 2, cv::LINE_AA);
        break;
      case 4: {
        std::vector<cv::Point> pts;
        const int n = r.I(3, 7);
        for (int k = 0; k < n; ++k) pts.push_back(c + cv::Point(r.I(-50, 50), r.I(-50, 50)));
        if (r.I(0, 1))
          cv::fillPoly(img, std::vector<std::vector<cv::Point>>{pts}, col, cv::LINE_AA);
        else
          cv::polylines(img, std::vector<std::vector<cv::Point>>{pts}, r.I(0, 1) == 1, col, r.I(1, 3), cv::LINE_AA);
        break;
      }
      default: {
        std::string s;
        const int n = r.I(2, 9);
        for (int k = 0; k < n; ++k) s += kChars[r.I(0, int(sizeof(kChars)) - 2)];
        cv::putText(img, s, cv::Point(r.I(-20, W - 20), r.I(10, H + 10)), kFonts[r.I(0, 5)], r.U(0.5, 2.2), col,
                    r.I(1, 3), cv::LINE_AA);
      }
    }
  }
}

// A procedural image of w x h: smooth noise background and shapes.
cv::Mat Procedural(Rng& r, int w, int h, int shapes) {
  cv::Mat img(h, w, CV_8UC1, cv::Scalar(r.U(30, 225)));
  cv::Mat tex(std::max(2, h / r.I(6, 24)), std::max(2, w / r.I(6, 24)), CV_8UC1);
  cv::RNG cvr(r.g());
  cvr.fill(tex, cv::RNG::UNIFORM, 0, 255);
  cv::Mat up;
  cv::resize(tex, up, img.size(), 0, 0, cv::INTER_CUBIC);
  cv::addWeighted(img, 0.5, up, 0.5, 0, img);
  DrawShapes(img, r, shapes);
  return img;
}

// Target `index` of the set drawn from `seed`: procedural canvas + photo patch + overlay.
cv::Mat MakeTarget(std::uint64_t seed, std::uint64_t index, const std::vector<cv::Mat>& photos) {
  Rng r(Mix(seed, index));
  const int w = r.I(200, 400), h = r.I(200, 400);
  cv::Mat img = Procedural(r, w, h, r.I(15, 40));
  if (!photos.empty()) {
    const cv::Mat& p = photos[std::size_t(r.I(0, int(photos.size()) - 1))];
    const int lo = int(std::min(w, h) * 0.35), hi = int(std::min(w, h) * 0.65);
    cv::Mat crop = PhotoCrop(p, r, lo, hi);
    const int x = r.I(0, w - crop.cols), y = r.I(0, h - crop.rows);
    crop.copyTo(img(cv::Rect(x, y, crop.cols, crop.rows)));
  }
  DrawShapes(img, r, r.I(3, 10));
  const int side = std::max(img.cols, img.rows);
  return side > 320 ? PrepareTarget(img, 320) : img;
}

// A non-target image: a crop of the holdout photo, or a procedural image drawn
// from a seed stream the targets never use.
cv::Mat MakeDistractor(std::uint64_t seed, std::uint64_t index, const cv::Mat& holdout) {
  Rng r(Mix(seed ^ 0xD1B54A32D192ED03ull, index));
  cv::Mat img;
  if (index % 2 == 0 && !holdout.empty()) {
    img = PhotoCrop(holdout, r, 200, 400);
  } else {
    img = Procedural(r, r.I(200, 400), r.I(200, 400), r.I(20, 50));
  }
  const int side = std::max(img.cols, img.rows);
  return side > 320 ? PrepareTarget(img, 320) : img;
}

struct Stat {
  double median = 0, mean = 0, p90 = 0, max = 0;
};
Stat Summarise(std::vector<double> v) {
  Stat s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  s.median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / double(n);
  s.p90 = v[std::min(n - 1, std::size_t(std::ceil(0.9 * double(n))) - 1)];
  s.max = v.back();
  return s;
}
nlohmann::json ToJson(const Stat& s) { return {{"median", s.median}, {"mean", s.mean}, {"p90", s.p90}, {"max", s.max}}; }

struct TrainedTarget {
  std::string id;
  cv::Mat image;
  Model model;
  double train_ms = 0;
  std::size_t serialized_bytes = 0;
  int attempts = 1;  // generated images tried (kNoTexture retries)
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Recognition speed and memory against the number of targets (issue 6)"};
  std::vector<int> sizes = {10, 100, 1000};
  int frames = 50, views = 50, locations = 200, clusters = 20, threads = 1;
  double negative_fraction = 0.2, max_corner_error = 10.0;
  std::uint64_t seed = 1;
  std::string json_out, cache_dir, samples_dir = std::string(MVKP_SOURCE_DIR) + "/samples", holdout = "fruits",
                        index = "exact";
  bool large = false;
  app.add_option("--sizes", sizes, "numbers of targets")->delimiter(',')->capture_default_str();
  app.add_option("--frames", frames, "frames per size")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--negative-fraction", negative_fraction, "fraction of frames with no target")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  app.add_option("--seed", seed, "drives targets, frames and training")->capture_default_str();
  app.add_option("--views", views, "TrainOptions::views")->capture_default_str();
  app.add_option("--locations", locations, "TrainOptions::locations")->capture_default_str();
  app.add_option("--clusters", clusters, "TrainOptions::clusters")->capture_default_str();
  app.add_option("--index", index, "--search exact: index kind, exact | approx | brute")->capture_default_str();
  std::string search = "words", vocab_file;
  RecognizerOptions ro_base;
  app.add_option("--search", search, "words (inverted file, default) | exact (all centres in one FFVA index)")
      ->check(CLI::IsMember({"words", "exact"}))
      ->capture_default_str();
  app.add_option("--vocab", vocab_file, "vocabulary file (default: the built-in one)");
  app.add_option("--max-locations", ro_base.max_locations, "words: locations kept per target")->capture_default_str();
  app.add_option("--words-per-location", ro_base.words_per_location, "words: postings per location")->capture_default_str();
  app.add_option("--max-hamming", ro_base.max_hamming, "words: signature bits that may differ")->capture_default_str();
  app.add_option("--probe-words", ro_base.probe_words, "exact: 0 = every centre, N = only those in the N nearest words")
      ->capture_default_str();
  app.add_option("--query-words", ro_base.query_words, "words: nearest words per query descriptor")->capture_default_str();
  app.add_option("--min-inliers", ro_base.min_inliers, "inliers to accept a target")->capture_default_str();
  auto* max_points_opt = app.add_option("--max-points", ro_base.match.max_points, "query points per frame (words: 600 unless given)");
  app.add_option("--min-votes", ro_base.min_votes, "votes to verify a target")->capture_default_str();
  app.add_option("--max-candidates", ro_base.max_candidates, "targets verified per frame")->capture_default_str();
  app.add_option("--max-corner-error", max_corner_error, "px, for a correct recognition")->capture_default_str();
  app.add_option("--threads", threads, "cv::setNumThreads")->capture_default_str();
  app.add_option("--samples", samples_dir, "directory of the sample photos (*.jpg)")->capture_default_str();
  app.add_option("--holdout", holdout, "sample photo (stem) kept out of the targets, used for no-target frames")
      ->capture_default_str();
  app.add_option("--cache", cache_dir, "directory for trained models, reused by later runs with the same settings");
  app.add_option("--json", json_out, "write the results as JSON");
  std::string dump_dir;
  app.add_option("--dump", dump_dir, "write the first 20 targets and a frame of each kind here (PNG)");
  app.add_flag("--large", large, "allow sizes above 1000 (training takes hours)");
  CLI11_PARSE(app, argc, argv);
  if (search == "words" && max_points_opt->count() == 0)
    ro_base.match.max_points = RecognizerOptions::Words().match.max_points;
  Vocabulary vocab;
  if (!vocab_file.empty()) {
    const auto bytes = ReadFileBytes(vocab_file);
    vocab = Vocabulary::Deserialize(bytes.data(), bytes.size(), vocab_file);
  }

  try {
    if (sizes.empty()) throw CLI::ValidationError("--sizes", "empty");
    for (int n : sizes)
      if (n <= 0 || (n > 1000 && !large))
        throw CLI::ValidationError("--sizes", "sizes must be in 1..1000 (above 1000 needs --large)");
  } catch (const CLI::Error& e) {
    return app.exit(e);
  }
  cv::setNumThreads(threads);

  // Photos.
  std::vector<cv::Mat> photos;
  std::vector<std::string> photo_names;
  cv::Mat holdout_photo;
  {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(samples_dir))
      if (e.path().extension() == ".jpg") files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      cv::Mat m = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
      if (m.empty()) continue;
      if (f.stem() == holdout) {
        holdout_photo = m;
      } else {
        photos.push_back(m);
        photo_names.push_back(f.stem().string());
      }
    }
    if (photos.empty()) std::fprintf(stderr, "warning: no sample photos in %s, targets are procedural only\n", samples_dir.c_str());
  }

  TrainOptions to;
  to.views = views;
  to.locations = locations;
  to.clusters = clusters;
  to.seed = seed;
  try {
    to.Check();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bad training options: %s\n", e.what());
    return 2;
  }
  if (!cache_dir.empty()) fs::create_directories(cache_dir);

  // Train the targets of the largest size once.
  const int max_n = *std::max_element(sizes.begin(), sizes.end());
  std::vector<TrainedTarget> targets;
  targets.reserve(std::size_t(max_n));
  std::uint64_t next_index = 0;
  int cached = 0;
  const auto train_start = Clock::now();
  while (int(targets.size()) < max_n) {
    TrainedTarget t;
    t.id = "t" + std::to_string(targets.size());
    for (;; ++t.attempts) {
      const std::uint64_t gi = next_index++;
      t.image = MakeTarget(seed, gi, photos);
      const std::string cache_file =
          cache_dir.empty() ? std::string()
                            : cache_dir + "/s" + std::to_string(seed) + "_g" + std::to_string(gi) + "_v" +
                                  std::to_string(views) + "_l" + std::to_string(locations) + "_c" +
                                  std::to_string(clusters) + ".mvkpm";
      if (!cache_file.empty() && fs::exists(cache_file)) {
        t.model = LoadModel(cache_file);
        t.train_ms = t.model.params.train_ms;
        ++cached;
        break;
      }
      try {
        const auto t0 = Clock::now();
        t.model = Train(t.image, to);
        t.train_ms = MsSince(t0);
        if (!cache_file.empty()) SaveModel(t.model, cache_file);
        break;
      } catch (const Error& e) {
        if (e.code() != ErrorCode::kNoTexture) throw;
        if (t.attempts > 20) throw;
      }
    }
    t.serialized_bytes = SerializeModel(t.model).size();
    targets.push_back(std::move(t));
    const int done = int(targets.size());
    if (done % 10 == 0 || done == max_n)
      std::fprintf(stderr, "\rtrained %d/%d targets (%.1f s)", done, max_n, MsSince(train_start) / 1000);
  }
  std::fprintf(stderr, "\n");
  if (cached) std::fprintf(stderr, "%d models from the cache (their train_ms is the recorded one)\n", cached);

  if (!dump_dir.empty()) {
    fs::create_directories(dump_dir);
    for (std::size_t i = 0; i < std::min<std::size_t>(20, targets.size()); ++i)
      cv::imwrite(dump_dir + "/target_" + std::to_string(i) + ".png", targets[i].image);
    cv::imwrite(dump_dir + "/frame_target.png", MakeSceneView(targets[0].image, SceneOptions{}, 7).image);
    for (int k = 0; k < 2; ++k)
      cv::imwrite(dump_dir + "/frame_none_" + std::to_string(k) + ".png",
                  MakeSceneView(MakeDistractor(seed, std::uint64_t(k), holdout_photo), SceneOptions{}, 8).image);
  }

  nlohmann::json jout;
  jout["settings"] = {{"frames", frames},
                      {"negative_fraction", negative_fraction},
                      {"seed", seed},
                      {"threads", threads},
                      {"frame_size", {640, 480}},
                      {"max_corner_error", max_corner_error},
                      {"index", index},
                      {"search", search},
                      {"words", {{"vocabulary", vocab.empty() ? DefaultVocabulary().size() : vocab.size()},
                                 {"max_locations", ro_base.max_locations},
                                 {"words_per_location", ro_base.words_per_location},
                                 {"max_hamming", ro_base.max_hamming},
                                 {"probe_words", ro_base.probe_words},
                                 {"query_words", ro_base.query_words}}},
                      {"min_inliers", ro_base.min_inliers},
                      {"max_points", ro_base.match.max_points},
                      {"min_votes", ro_base.min_votes},
                      {"train", {{"views", views}, {"locations", locations}, {"clusters", clusters},
                                 {"rotation_views", to.rotation_views}, {"points_per_view", to.points_per_view},
                                 {"select", SelectionName(to.select)}}},
                      {"photos", photo_names},
                      {"holdout", holdout},
                      {"models_from_cache", cached}};
  jout["sizes"] = nlohmann::json::array();

  std::printf("training: views %d, locations %d, clusters %d, selection %s; frames %d (%.0f%% no target), "
              "640x480, %d thread(s), index %s, seed %llu\n",
              views, locations, clusters, SelectionName(to.select), frames, negative_fraction * 100, threads,
              index.c_str(), (unsigned long long)seed);
  std::printf("%6s | %9s %9s | %7s %7s %7s %7s | %7s %6s %6s | %9s %9s | %8s %7s %8s | %5s %5s %5s\n", "N",
              "med_ms", "mean_ms", "detect", "descr", "search", "verify", "recall", "wrong", "falseP",
              "mem/tgt", "ser/tgt", "train_ms", "add_ms", "build_ms", "kpts", "match", "cand");

  for (int n : sizes) {
    RecognizerOptions ro = ro_base;
    ro.match.index = index;
    ro.search = search == "exact" ? RecognizerSearch::kExact : RecognizerSearch::kWords;
    Recognizer rec(ro, vocab.empty() ? nullptr : &vocab);
    const auto ta = Clock::now();
    for (int i = 0; i < n; ++i) rec.Add(targets[std::size_t(i)].id, targets[std::size_t(i)].model);
    const double add_ms = MsSince(ta);
    // Words: loading from stored encodings (what `recognize` does with a
    // database made by `db add`) instead of encoding every model.
    double add_encoded_ms = 0, encoded_bytes = 0;
    if (ro.search == RecognizerSearch::kWords) {
      std::vector<std::vector<std::uint8_t>> enc;
      for (int i = 0; i < n; ++i) enc.push_back(rec.Encode(targets[std::size_t(i)].model));
      Recognizer again(ro, vocab.empty() ? nullptr : &vocab);
      const auto te = Clock::now();
      for (int i = 0; i < n; ++i) again.AddEncoded(targets[std::size_t(i)].id, enc[std::size_t(i)].data(), enc[std::size_t(i)].size());
      add_encoded_ms = MsSince(te) / n;
      for (const auto& e : enc) encoded_bytes += double(e.size()) / n;
    }
    const auto tb = Clock::now();
    rec.ShrinkToFit();
    const std::size_t mem = rec.memory_bytes();  // builds the index (exact)
    const double build_ms = MsSince(tb);
    double train_sum = 0, ser_sum = 0, centres = 0, locs = 0;
    for (int i = 0; i < n; ++i) {
      train_sum += targets[std::size_t(i)].train_ms;
      ser_sum += double(targets[std::size_t(i)].serialized_bytes);
      centres += targets[std::size_t(i)].model.descriptors.rows;
      locs += double(targets[std::size_t(i)].model.locations.size());
    }

    const int neg = int(std::lround(frames * negative_fraction));
    const int pos = frames - neg;
    Rng fr(Mix(seed ^ 0x5851F42D4C957F2Dull, std::uint64_t(n)));
    // Frame k is negative for an even spread of `neg` frames.
    std::vector<int> is_neg(std::size_t(frames), 0);
    for (int k = 0; k < neg; ++k) is_neg[std::size_t((2 * k + 1) * frames / (2 * neg))] = 1;

    std::vector<double> total, detect, describe, search, verify, kpts, matches, cands;
    int recall = 0, found_any_pos = 0, wrong_frames = 0, wrong_ids = 0, false_frames = 0, false_ids = 0;
    std::vector<double> corner_errors;
    int neg_index = 0;
    // Warm-up (caches, allocator) on a throw-away frame.
    {
      const SceneView v = MakeSceneView(targets[0].image, SceneOptions{}, Mix(seed, 0xFFFF));
      (void)rec.Recognize(v.image);
    }
    for (int k = 0; k < frames; ++k) {
      const std::uint64_t scene_seed = fr.g();
      int truth = -1;
      SceneView v;
      if (is_neg[std::size_t(k)]) {
        const cv::Mat d = MakeDistractor(seed, std::uint64_t(n) * 100000 + std::uint64_t(neg_index++), holdout_photo);
        v = MakeSceneView(d, SceneOptions{}, scene_seed);
      } else {
        truth = fr.I(0, n - 1);
        v = MakeSceneView(targets[std::size_t(truth)].image, SceneOptions{}, scene_seed);
      }
      const auto t0 = Clock::now();
      const RecognitionResult r = rec.Recognize(v.image);
      total.push_back(MsSince(t0));
      detect.push_back(r.detect_ms);
      describe.push_back(r.describe_ms);
      search.push_back(r.search_ms);
      verify.push_back(r.verify_ms);
      kpts.push_back(r.keypoints);
      matches.push_back(r.matches);
      cands.push_back(r.candidates);
      if (truth < 0) {
        false_frames += !r.found.empty();
        false_ids += int(r.found.size());
      } else {
        const std::string& id = targets[std::size_t(truth)].id;
        found_any_pos += !r.found.empty();
        if (!r.found.empty() && r.found[0].id == id) {
          const double err = MeanCornerError(r.found[0].homography, v.H, targets[std::size_t(truth)].image.size());
          corner_errors.push_back(err);
          recall += err < max_corner_error;
        }
        int w = 0;
        for (const auto& f : r.found) w += f.id != id;
        wrong_ids += w;
        wrong_frames += w > 0;
      }
    }
    const Stat st = Summarise(total), sd = Summarise(detect), sdc = Summarise(describe), ss = Summarise(search),
               sv = Summarise(verify), sk = Summarise(kpts), sm = Summarise(matches), sc = Summarise(cands);
    const double mem_per = double(mem) / n, ser_per = ser_sum / n, train_per = train_sum / n;
    std::printf("%6d | %9.2f %9.2f | %7.2f %7.2f %7.2f %7.2f | %3d/%-3d %6d %3d/%-2d | %8.1fK %8.1fK | %8.0f %7.3f %8.1f | %5.0f %5.0f %5.1f\n",
                n, st.median, st.mean, sd.mean, sdc.mean, ss.mean, sv.mean, recall, pos, wrong_frames, false_frames, neg,
                mem_per / 1024, ser_per / 1024, train_per, add_ms / n, build_ms, sk.mean, sm.mean, sc.mean);
    if (add_encoded_ms > 0)
      std::printf("       words: %.0f B encoding per target, AddEncoded %.4f ms per target (Add from the model %.3f)\n",
                  encoded_bytes, add_encoded_ms, add_ms / n);
    std::fflush(stdout);
    jout["sizes"].push_back({{"n", n},
                             {"frames", frames},
                             {"positive_frames", pos},
                             {"negative_frames", neg},
                             {"ms_total", ToJson(st)},
                             {"ms_detect", ToJson(sd)},
                             {"ms_describe", ToJson(sdc)},
                             {"ms_search", ToJson(ss)},
                             {"ms_verify", ToJson(sv)},
                             {"keypoints", ToJson(sk)},
                             {"matches", ToJson(sm)},
                             {"candidates", ToJson(sc)},
                             {"recall_top1", pos ? double(recall) / pos : 0.0},
                             {"correct_top1", recall},
                             {"positive_frames_with_detection", found_any_pos},
                             {"corner_error_top1_right_id", ToJson(Summarise(corner_errors))},
                             {"wrong_id_frames", wrong_frames},
                             {"wrong_ids", wrong_ids},
                             {"false_detection_frames", false_frames},
                             {"false_detections", false_ids},
                             {"memory_bytes", mem},
                             {"memory_bytes_per_target", mem_per},
                             {"serialized_bytes_per_target", ser_per},
                             {"centres_per_target", centres / n},
                             {"locations_per_target", locs / n},
                             {"train_ms_per_target", train_per},
                             {"add_ms_total", add_ms},
                             {"add_ms_per_target", add_ms / n},
                             {"index_build_ms", build_ms},
                             {"add_encoded_ms_per_target", add_encoded_ms},
                             {"encoded_bytes_per_target", encoded_bytes}});
  }
  std::printf("med/mean_ms: wall clock per Recognize; detect..verify: mean ms per stage; recall: top-1 right id "
              "within %.0f px (of target frames); wrong: target frames with a wrong id; falseP: no-target frames "
              "with a detection; mem/tgt: memory_bytes()/N; ser/tgt: SerializeModel bytes; train_ms: mean per "
              "target; add_ms: Add per target; build_ms: index build (first memory_bytes)\n",
              max_corner_error);
  if (!json_out.empty()) {
    std::ofstream f(json_out);
    f << jout.dump(2) << "\n";
    if (!f) {
      std::fprintf(stderr, "cannot write %s\n", json_out.c_str());
      return 1;
    }
  }
  return 0;
}
