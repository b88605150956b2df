#include "mvkp/quality/quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {
namespace {

std::string Fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

// Grey levels between the 0.5th and 99.5th intensity percentiles.
double ContrastSpread(const cv::Mat& in) {
  int hist[256] = {0};
  for (int y = 0; y < in.rows; ++y) {
    const std::uint8_t* r = in.ptr<std::uint8_t>(y);
    for (int x = 0; x < in.cols; ++x) ++hist[r[x]];
  }
  const double n = double(in.total());
  auto pct = [&](double q) {
    double acc = 0;
    for (int v = 0; v < 256; ++v) {
      acc += hist[v];
      if (acc >= q * n) return v;
    }
    return 255;
  };
  return std::max(0, pct(0.995) - pct(0.005));
}

// Share of 16x16 cells whose mean gradient magnitude shows structure.
double TextureShare(const cv::Mat& img) {
  cv::Mat s, gx, gy, mag;
  cv::GaussianBlur(img, s, cv::Size(), 1.0);
  cv::Sobel(s, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(s, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  cv::magnitude(gx, gy, mag);
  const int cell = 16;
  int cells = 0, textured = 0;
  for (int y = 0; y + cell <= img.rows; y += cell)
    for (int x = 0; x + cell <= img.cols; x += cell) {
      ++cells;
      textured += cv::mean(mag(cv::Rect(x, y, cell, cell)))[0] > 6.0;  // grey levels per pixel
    }
  return cells ? double(textured) / cells : 0.0;
}

// Median over the model's locations of (distance from the location's mean
// descriptor to the nearest other location's mean) / (mean distance between
// locations, DS of SPEC §4). Repeated elements (tiles, brick, letters) give
// groups of locations whose means nearly coincide, so the ratio drops.
// *lookalike_share receives the share of locations below `rel`.
double DistinctRatio(const Model& m, double rel, double* lookalike_share) {
  *lookalike_share = 1;
  const int nl = int(m.locations.size()), d = m.descriptors.cols;
  if (nl < 2) return 0;
  std::vector<double> mean(std::size_t(nl) * d, 0.0);
  std::vector<int> count(nl, 0);
  for (int i = 0; i < m.descriptors.rows; ++i) {
    const float* r = m.descriptors.ptr<float>(i);
    for (int l = 0; l < d; ++l) mean[std::size_t(m.labels[i]) * d + l] += r[l];
    ++count[m.labels[i]];
  }
  for (int j = 0; j < nl; ++j)
    for (int l = 0; l < d; ++l) mean[std::size_t(j) * d + l] /= std::max(1, count[j]);
  std::vector<double> nn(nl, INFINITY);
  double sum = 0;
  for (int a = 0; a < nl; ++a)
    for (int b = a + 1; b < nl; ++b) {
      double d2 = 0;
      for (int l = 0; l < d; ++l) {
        const double t = mean[std::size_t(a) * d + l] - mean[std::size_t(b) * d + l];
        d2 += t * t;
      }
      const double dist = std::sqrt(d2);
      sum += 2 * dist;
      nn[a] = std::min(nn[a], dist);
      nn[b] = std::min(nn[b], dist);
    }
  const double ds = sum / (double(nl) * (nl - 1));
  int distinct = 0;
  for (int j = 0; j < nl; ++j) distinct += nn[j] >= rel * ds;
  *lookalike_share = 1.0 - double(distinct) / nl;
  std::nth_element(nn.begin(), nn.begin() + nl / 2, nn.end());
  return nn[nl / 2] / ds;
}

double CoverageShare(const std::vector<cv::Point2f>& pts, cv::Size size) {
  const int g = 6;
  std::vector<char> hit(g * g, 0);
  for (const auto& p : pts) {
    const int cx = std::clamp(int(p.x * g / size.width), 0, g - 1);
    const int cy = std::clamp(int(p.y * g / size.height), 0, g - 1);
    hit[cy * g + cx] = 1;
  }
  return std::count(hit.begin(), hit.end(), 1) / double(g * g);
}

}  // namespace

void QualityOptions::Check() const {
  Require(target_size >= 64 && target_size <= 4096, ErrorCode::kInvalidArgument, "target size must be in 64..4096");
  Require(test_views >= 1 && test_views <= 10000, ErrorCode::kInvalidArgument, "test views must be in 1..10000");
  Require(success_px > 0, ErrorCode::kInvalidArgument, "success threshold must be > 0 px");
  Require(half_rate > 0 && half_rate <= 1, ErrorCode::kInvalidArgument, "half rate must be in (0, 1]");
  Require(min_contrast >= 0 && min_contrast <= 255, ErrorCode::kInvalidArgument, "min contrast must be in 0..255");
  const double w = w_detection + w_stable + w_distinct + w_texture + w_coverage;
  Require(std::abs(w - 1.0) < 1e-6 && w_detection >= 0 && w_stable >= 0 && w_distinct >= 0 && w_texture >= 0 &&
              w_coverage >= 0,
          ErrorCode::kInvalidArgument, "quality weights must be >= 0 and sum to 1");
  Require(good_stable_tracks >= 1 && good_texture > 0 && good_coverage > 0 && good_distinct > repeated_distinct,
          ErrorCode::kInvalidArgument, "quality targets must be positive");
  Require(min_size >= 8 && max_size >= min_size && size_tilt >= 0 && size_tilt < 90 && max_tilt >= 0 && max_tilt < 90 &&
              tilt_size_min >= 8 && tilt_size_max >= tilt_size_min,
          ErrorCode::kInvalidArgument, "quality envelope: need 8 <= min <= max sizes and tilts in [0, 90)");
  Require(std::max(max_size, tilt_size_max) <= std::max(scene.width, scene.height), ErrorCode::kInvalidArgument,
          "quality envelope: sizes must fit the test frame");
  train.Check();
  match.Check();
  scene.Check();
}

QualityReport AssessTarget(const cv::Mat& input, const QualityOptions& o) {
  o.Check();
  Require(!input.empty() && input.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "quality needs a non-empty 8-bit grayscale image");
  Timer timer;
  QualityReport rep;
  rep.test_views = o.test_views;
  auto finish = [&](int score, const std::string& code, const std::string& msg) {
    rep.score = score;
    rep.verdict = "poor";
    rep.reasons.push_back({code, msg, 100.0});
    rep.ms = timer.ElapsedMs();
    return rep;
  };
  if (std::min(input.cols, input.rows) < 32)
    return finish(0, "too_small",
                  Fmt("image is %.0fx%.0f pixels; a target needs at least 32 pixels on each side (better: 300+)",
                      input.cols, input.rows));
  const double spread = ContrastSpread(input);
  if (spread < o.min_contrast)
    return finish(0, "uniform",
                  Fmt("image is nearly uniform (99%% of its pixels lie within %.0f grey levels, %.0f needed): nothing "
                      "a camera can recognise",
                      spread, o.min_contrast));

  // The structural factors at a fixed size (their thresholds are in pixels of it).
  const cv::Mat small = PrepareTarget(input, o.target_size);
  const double to_small = double(std::max(small.cols, small.rows)) / std::max(input.cols, input.rows);
  const double texture = TextureShare(small);

  // The model exactly as `mvkp train` builds it, from the image as given.
  TrainOptions to = o.train;
  to.progress = nullptr;
  TrainReport tr;
  Model model;
  bool trained = true;
  try {
    model = Train(input, to, &tr);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kNoTexture) throw;
    trained = false;
  }
  double soft = 0, hard = 0;
  std::vector<double> errs;
  double distinct = 0, coverage = 0, lookalike_share = 1;
  if (trained) {
    // Stable points and coverage count the top level (the target as trained
    // at full size); the smaller levels repeat it coarser.
    rep.eligible_tracks = 0;
    rep.selected_tracks = tr.kept;
    rep.train_side = tr.level_sizes.empty() ? 0 : tr.level_sizes[0];
    std::vector<cv::Point2f> sel;
    for (const auto& t : tr.tracks) {
      if (t.rank < 0) continue;
      if (t.level == 0) ++rep.eligible_tracks;
      const cv::Point2f p(t.x, t.y);
      (t.kept ? rep.selected : rep.rejected).push_back(p);
      if (t.kept && t.level == 0) sel.push_back(p * float(to_small));
    }
    distinct = DistinctRatio(model, o.lookalike, &lookalike_share);
    coverage = CoverageShare(sel, small.size());
    const Matcher matcher(model, o.match);
    const cv::Size frame(o.scene.width, o.scene.height);
    cv::Mat colour_target;
    cv::cvtColor(input, colour_target, cv::COLOR_GRAY2BGR);
    std::mt19937_64 rng(o.seed);
    auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
    for (int i = 0; i < o.test_views; ++i) {
      // Stratified over the envelope: even views over size, odd over tilt.
      const double u = (i / 2 + U(0, 1)) / ((o.test_views + 1) / 2);
      CameraPose pose;
      if (i % 2 == 0) {
        pose.size_px = o.min_size * std::pow(o.max_size / o.min_size, u);
        pose.tilt_deg = U(0, o.size_tilt);
      } else {
        pose.size_px = std::exp(U(std::log(o.tilt_size_min), std::log(o.tilt_size_max)));
        pose.tilt_deg = o.max_tilt * u;
      }
      pose.azimuth_deg = U(0, 360);
      pose.roll_deg = U(0, 360);
      const std::uint64_t seed = o.seed * 1000003ull + std::uint64_t(i);
      const cv::Mat bg = MakeClutterBackground(frame, seed ^ 0xC1u);
      const CameraScene v = MakeCameraScene(input, bg, pose, o.scene, seed);
      const MatchResult r = matcher.Match(v.image);
      const double err = r.found ? MeanCornerError(r.homography, v.H, input.size()) : INFINITY;
      if (err < o.success_px) {
        hard += 1;
        errs.push_back(err);
      }
      // Soft credit: 1 within success_px, falling to 0 at twice that.
      soft += std::clamp((2 * o.success_px - err) / o.success_px, 0.0, 1.0);
    }
    hard /= o.test_views;
    soft /= o.test_views;
  } else {
    rep.eligible_tracks = 0;
  }
  rep.detection_rate = hard;
  if (!errs.empty()) {
    std::sort(errs.begin(), errs.end());
    rep.median_error_px = errs[errs.size() / 2];
  }

  // Structure only counts in full once the target is actually found: its
  // points are scaled by min(1, soft rate / half_rate); what the scaling
  // takes is charged to detection.
  const double gate = std::min(1.0, soft / o.half_rate);
  double gated = 0;
  auto factor = [&](const char* name, double value, double f, double w, double g) {
    QualityFactor q{name, value, std::clamp(f, 0.0, 1.0), w, 0, 0};
    q.points = 100 * w * q.factor * g;
    q.lost = 100 * w * (1 - q.factor);  // its own weakness, gated or not; points + lost + gated = 100 * w
    gated += 100 * w * q.factor * (1 - g);
    rep.factors.push_back(q);
    return q;
  };
  factor("detection", hard, soft, o.w_detection, 1.0);
  const auto fs =
      factor("stable_points", rep.eligible_tracks, double(rep.eligible_tracks) / o.good_stable_tracks, o.w_stable, gate);
  const auto fr = factor("distinctiveness", distinct,
                         (distinct - o.repeated_distinct) / (o.good_distinct - o.repeated_distinct), o.w_distinct, gate);
  const auto ft = factor("texture", texture, texture / o.good_texture, o.w_texture, gate);
  const auto fc = factor("coverage", coverage, coverage / o.good_coverage, o.w_coverage, gate);
  rep.factors[0].lost += gated;
  const QualityFactor& fd = rep.factors[0];
  double total = 0;
  for (const auto& f : rep.factors) total += f.points;
  rep.score = std::clamp(int(std::lround(total)), 0, 100);
  rep.verdict = rep.score >= 80 ? "excellent" : rep.score >= 60 ? "good" : rep.score >= 40 ? "fair" : "poor";

  const double min_lost = 1.0;  // points; smaller weaknesses are not worth a reason
  auto weak = [&](const QualityFactor& f) { return f.lost >= min_lost; };
  if (weak(fd) && trained) {
    // Says what was measured, over the envelope actually used; the gate is
    // mentioned only when it took points (the soft rate is below half_rate).
    std::string msg = Fmt("found within %.0f px in %.0f%% of camera-model test frames", o.success_px, 100 * hard) +
                      Fmt(" (%.0f-%.0f px,", o.min_size, o.max_size) +
                      Fmt(" tilts up to %.0f degrees, busy backgrounds, dim lighting, blur, noise)",
                          std::max(o.size_tilt, o.max_tilt));
    if (gated >= 0.5)
      msg += Fmt("; that is below %.0f%%, so the other factors count only in part (%.0f points held back)",
                 100 * o.half_rate, gated);
    rep.reasons.push_back({"low_detection", msg, fd.lost});
  }
  if (!trained)
    rep.reasons.push_back({"few_stable_points",
                           "too few stable interest points to train a target at all: the image needs texture "
                           "(corners, detail) over most of its area",
                           fs.lost});
  else if (weak(fs))
    rep.reasons.push_back(
        {"few_stable_points",
         Fmt("only %.0f stable points when trained at %.0f px (seen in enough training views; %.0f or more is "
             "good): add detail or use a more textured image",
             rep.eligible_tracks, rep.train_side, o.good_stable_tracks),
         fs.lost});
  if (weak(fr) && trained)
    rep.reasons.push_back({"repeated_elements",
                           Fmt("points look alike: %.0f%% of the selected points have a near twin elsewhere in "
                               "the image (repeated elements such as tiles, brick, windows or text)",
                               100 * lookalike_share),
                           fr.lost});
  if (weak(ft))
    rep.reasons.push_back({"low_texture",
                           Fmt("only %.0f%% of the image has texture; flat areas give no points", 100 * texture),
                           ft.lost});
  if (weak(fc) && trained)
    rep.reasons.push_back({"concentrated",
                           Fmt("the selected points cover %.0f%% of the image: features are concentrated in a small "
                               "area, so the target is lost when that part is hidden or out of view",
                               100 * coverage),
                           fc.lost});
  std::stable_sort(rep.reasons.begin(), rep.reasons.end(),
                   [](const QualityReason& a, const QualityReason& b) { return a.lost > b.lost; });
  rep.ms = timer.ElapsedMs();
  return rep;
}

cv::Mat DrawQuality(const cv::Mat& image, const QualityReport& r) {
  cv::Mat out;
  if (image.channels() == 1) cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  else out = image.clone();
  const double s = std::max(1.0, std::max(out.cols, out.rows) / 640.0);
  const int arm = int(std::lround(4 * s)), th = std::max(1, int(std::lround(s)));
  for (const auto& p : r.rejected) cv::circle(out, p, th, cv::Scalar(128, 128, 128), cv::FILLED, cv::LINE_AA);
  // White pluses with a dark outline, visible on any background: every
  // outline first, so a neighbour's (the same point at another pyramid
  // level) never covers a plus.
  for (const auto& [c, t] : {std::pair{cv::Scalar(0, 0, 0), th + 2}, std::pair{cv::Scalar(255, 255, 255), th}})
    for (const auto& p : r.selected) {
      cv::line(out, p - cv::Point2f(float(arm), 0), p + cv::Point2f(float(arm), 0), c, t, cv::LINE_AA);
      cv::line(out, p - cv::Point2f(0, float(arm)), p + cv::Point2f(0, float(arm)), c, t, cv::LINE_AA);
    }
  const std::string label = "quality " + std::to_string(r.score) + "/100 (" + r.verdict + ")";
  const double fs = 0.6 * s;
  int base = 0;
  const cv::Size ts = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, fs, th, &base);
  cv::rectangle(out, cv::Rect(0, 0, ts.width + 12, ts.height + base + 12), cv::Scalar(0, 0, 0), cv::FILLED);
  const cv::Scalar col = r.score >= 60 ? cv::Scalar(80, 220, 80) : r.score >= 40 ? cv::Scalar(60, 200, 240)
                                                                                 : cv::Scalar(60, 60, 230);
  cv::putText(out, label, cv::Point(6, ts.height + 6), cv::FONT_HERSHEY_SIMPLEX, fs, col, th, cv::LINE_AA);
  return out;
}

}  // namespace mvkp
