// mvkp_cdikp_tune: chooses CDIKP's patch size and scale factor (issue 5).
// On Oxford sequences (img1..img6 with ground-truth H1to2p..H1to6p) it detects
// SIFT keypoints once per image, describes them with CDIKP for every
// (patch_size, scale_factor) setting and with OpenCV SIFT (128-D), matches img1
// to imgN (BFMatcher, ratio 0.8, findHomography RANSAC 3 px) and reports per
// setting:
//   success   share of pairs whose homography maps the 4 corners of img1 to
//             within 10 px (mean corner error) of the ground truth;
//   correct   mean count of ratio-test matches within 3 px under the ground truth;
//   us/kp     description time per keypoint (compute() on the given keypoints,
//             pyramid included; best of --repeat runs), single thread.
//   mvkp_cdikp_tune [DATA_DIR] [--seqs bikes boat graf leuven] [--patch 16 32] [--scale 4 6 8 10 12]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mvkp/cdikp/cdikp.h"

namespace fs = std::filesystem;

namespace {

struct Image {
  cv::Mat gray;
  std::vector<cv::KeyPoint> kps;
};

struct Pair {
  std::string seq;
  int n;
  cv::Mat H;  // img1 -> imgN
};

cv::Mat LoadH(const std::string& path) {
  std::ifstream in(path);
  cv::Mat H(3, 3, CV_64F);
  for (int i = 0; i < 9; ++i) {
    if (!(in >> H.at<double>(i / 3, i % 3))) throw std::runtime_error("cannot read homography " + path);
  }
  return H;
}

cv::Point2d Apply(const cv::Mat& H, cv::Point2d p) {
  const double* h = H.ptr<double>(0);
  const double z = h[6] * p.x + h[7] * p.y + h[8];
  return {(h[0] * p.x + h[1] * p.y + h[2]) / z, (h[3] * p.x + h[4] * p.y + h[5]) / z};
}

struct Score {
  bool success = false;
  int correct = 0, ratio = 0;
  double corner_error = std::numeric_limits<double>::infinity();
};

Score MatchPair(const cv::Mat& d1, const std::vector<cv::KeyPoint>& k1, const cv::Mat& d2,
                const std::vector<cv::KeyPoint>& k2, const cv::Mat& H_true, cv::Size size1) {
  Score s;
  if (d1.empty() || d2.empty()) return s;
  cv::BFMatcher bf(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  bf.knnMatch(d1, d2, knn, 2);
  std::vector<cv::Point2f> p1, p2;
  for (const auto& m : knn) {
    if (m.size() < 2 || !(m[0].distance < 0.8f * m[1].distance)) continue;
    const cv::Point2f a = k1[m[0].queryIdx].pt, b = k2[m[0].trainIdx].pt;
    p1.push_back(a);
    p2.push_back(b);
    if (cv::norm(Apply(H_true, a) - cv::Point2d(b)) < 3.0) ++s.correct;
  }
  s.ratio = int(p1.size());
  if (p1.size() < 4) return s;
  const cv::Mat H = cv::findHomography(p1, p2, cv::RANSAC, 3.0);
  if (H.empty()) return s;
  double err = 0;
  const double w = size1.width - 1, h = size1.height - 1;
  for (cv::Point2d c : {cv::Point2d(0, 0), cv::Point2d(w, 0), cv::Point2d(0, h), cv::Point2d(w, h)})
    err += cv::norm(Apply(H, c) - Apply(H_true, c)) / 4;
  s.corner_error = err;
  s.success = err < 10.0;
  return s;
}

template <class F>
double BestSeconds(int repeat, F&& f) {
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

struct Method {
  std::string name;
  int patch = 0;
  double scale = 0;
  cv::Ptr<cv::Feature2D> f;
  std::vector<std::vector<cv::Mat>> desc;  // [seq][image]
  double seconds = 0;
  long keypoints = 0;
  std::vector<Score> scores;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Tune CDIKP (patch size, scale factor) against OpenCV SIFT on Oxford sequences"};
  std::string data = "../shared/data/oxford";
  std::vector<std::string> seqs{"bikes", "boat", "graf", "leuven"};
  std::vector<int> patches{16, 32};
  std::vector<double> scales{4, 6, 8, 10, 12};
  int repeat = 3;
  bool per_pair = false;
  app.add_option("DATA_DIR", data, "folder holding one folder per sequence");
  app.add_option("--seqs", seqs);
  app.add_option("--patch", patches);
  app.add_option("--scale", scales);
  app.add_option("--repeat", repeat, "timing runs per image; the best counts")->check(CLI::PositiveNumber);
  app.add_flag("--per-pair", per_pair, "print the corner error of every pair");
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);

  std::vector<Method> methods;
  {
    Method sift;
    sift.name = "SIFT-128";
    sift.f = cv::SIFT::create();
    methods.push_back(std::move(sift));
  }
  for (int p : patches)
    for (double s : scales) {
      Method m;
      mvkp::CdikpOptions o;
      o.patch_size = p;
      o.scale_factor = s;
      m.name = "CDIKP-" + std::to_string(o.dims);
      m.patch = p;
      m.scale = s;
      m.f = mvkp::CDIKP::create(o);
      methods.push_back(std::move(m));
    }

  cv::Ptr<cv::SIFT> detector = cv::SIFT::create();
  std::vector<std::vector<Image>> images;
  std::vector<Pair> pairs;
  double detect_s = 0;
  long detect_kps = 0;
  for (std::size_t q = 0; q < seqs.size(); ++q) {
    const fs::path dir = fs::path(data) / seqs[q];
    auto& imgs = images.emplace_back();
    for (int n = 1; n <= 6; ++n) {
      fs::path file;
      for (const char* ext : {".ppm", ".pgm", ".png", ".jpg"})
        if (fs::exists(dir / ("img" + std::to_string(n) + ext))) file = dir / ("img" + std::to_string(n) + ext);
      if (file.empty()) {
        std::fprintf(stderr, "error: no img%d in %s\n", n, dir.c_str());
        return 1;
      }
      Image im;
      im.gray = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
      if (im.gray.empty()) {
        std::fprintf(stderr, "error: cannot read %s\n", file.c_str());
        return 1;
      }
      detect_s += BestSeconds(1, [&] { detector->detect(im.gray, im.kps); });
      detect_kps += long(im.kps.size());
      imgs.push_back(std::move(im));
      if (n > 1) pairs.push_back({seqs[q], n, LoadH((dir / ("H1to" + std::to_string(n) + "p")).string())});
    }
  }

  for (auto& m : methods) {
    m.desc.resize(images.size());
    for (std::size_t q = 0; q < images.size(); ++q)
      for (auto& im : images[q]) {
        cv::Mat d;
        std::vector<cv::KeyPoint> k;
        m.seconds += BestSeconds(repeat, [&] {
          k = im.kps;
          m.f->compute(im.gray, k, d);
        });
        if (k.size() != im.kps.size()) {
          std::fprintf(stderr, "error: %s changed the keypoint count\n", m.name.c_str());
          return 1;
        }
        m.keypoints += long(k.size());
        m.desc[q].push_back(d);
      }
    for (const auto& p : pairs) {
      const std::size_t q = std::size_t(std::find(seqs.begin(), seqs.end(), p.seq) - seqs.begin());
      const auto& a = images[q][0];
      const auto& b = images[q][std::size_t(p.n - 1)];
      m.scores.push_back(MatchPair(m.desc[q][0], a.kps, m.desc[q][std::size_t(p.n - 1)], b.kps, p.H, a.gray.size()));
    }
  }

  std::printf("Oxford %zu sequences, %zu pairs (img1 -> img2..6), %.0f SIFT keypoints per image (detect %.0f ms/image)\n",
              seqs.size(), pairs.size(), double(detect_kps) / (6.0 * seqs.size()),
              1e3 * detect_s / (6.0 * seqs.size()));
  std::printf("BFMatcher L2, ratio 0.8, findHomography RANSAC 3 px; success = mean corner error < 10 px\n\n");
  std::printf("| method | patch | scale | success | correct matches | ratio matches | us/keypoint |");
  for (const auto& s : seqs) std::printf(" %s |", s.c_str());
  std::printf("\n|---|---|---|---|---|---|---|");
  for (std::size_t i = 0; i < seqs.size(); ++i) std::printf("---|");
  std::printf("\n");
  for (const auto& m : methods) {
    double succ = 0, corr = 0, ratio = 0;
    for (const auto& s : m.scores) {
      succ += s.success;
      corr += s.correct;
      ratio += s.ratio;
    }
    const double np = double(m.scores.size());
    std::printf("| %s | %s | %s | %.2f | %.1f | %.1f | %.2f |", m.name.c_str(),
                m.patch ? std::to_string(m.patch).c_str() : "-",
                m.scale > 0 ? cv::format("%g", m.scale).c_str() : "-", succ / np, corr / np, ratio / np,
                1e6 * m.seconds / double(m.keypoints));
    for (const auto& s : seqs) {
      int ok = 0, n = 0;
      for (std::size_t i = 0; i < pairs.size(); ++i)
        if (pairs[i].seq == s) {
          ++n;
          ok += m.scores[i].success;
        }
      std::printf(" %d/%d |", ok, n);
    }
    std::printf("\n");
    if (per_pair) {
      for (std::size_t i = 0; i < pairs.size(); ++i)
        std::printf("    %s 1->%d: corner error %.1f px, correct %d, ratio %d\n", pairs[i].seq.c_str(), pairs[i].n,
                    m.scores[i].corner_error, m.scores[i].correct, m.scores[i].ratio);
    }
  }
  return 0;
}
