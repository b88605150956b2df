// mvkp_video_track: following a target through video — full search on every
// frame, temporal focus (thesis §6.3.1), and focus + optical-flow tracking
// between detections (mvkp/track, issue 6 "video").
//
// --videos clips of --frames 640x480 frames are generated in memory,
// deterministically from --seed. Clip k shows target k (mod the number of
// targets; the targets are sample photos, PrepareTarget to 320 px, trained
// with `db add`'s settings and all held by one Recognizer) lying on a large
// cluttered plane (crops of the non-target sample photos and shapes), filmed by
// a moving camera: smooth pan, zoom 0.5-1.5, rotation up to ±35°, perspective
// tilt, hand shake, slow brightness and contrast drift, Gaussian noise on every
// frame and motion blur on some. In the middle of each clip the camera pans
// away until the target is out of view for a stretch, then back.
//
// Every mode sees the same frames through mvkp::VideoFollower (the policy of
// `mvkp video`), single threaded (cv::setNumThreads(1)). Per mode:
//   ms        median / mean / p95 wall-clock per frame (recogniser + tracker)
//   found     visible frames (>= 50 % of the target inside the frame) where the
//             target is reported with mean corner error < --max-corner-error
//   stays     the same, counted only after the clip's first correct detection
//             ("once found it stays found")
//   lost      found -> not found transitions between visible frames after that
//   err       mean corner error (px) of the correct detections vs ground truth
//   jitter    mean frame-to-frame change of the corner error vector (px; mean
//             over the 4 corners of |e_t - e_{t-1}|), consecutive correct frames
//   wrong     visible or partly visible frames with a wrong id or a wrong pose
//   falseP    frames with the target out of view where something is reported
//
//   mvkp_video_track [--videos 3] [--frames 300] [--seed 1] [--modes full,focus,klt]
//                    [--redetect-every 10] [--agree-px 2] [--per-video] [--json OUT] [--dump DIR]
// MVKP_BENCH_DEBUG=1 prints every frame with a wrong pose or id to stderr.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
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

#include "mvkp/core/error.h"
#include "mvkp/match/matcher.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/synth/synth.h"
#include "mvkp/track/follower.h"
#include "mvkp/train/trainer.h"

#ifndef MVKP_SOURCE_DIR
#define MVKP_SOURCE_DIR "."
#endif

using namespace mvkp;

namespace {

constexpr int kW = 640, kH = 480;

struct Rng {
  std::mt19937_64 g;
  explicit Rng(std::uint64_t s) : g(s) {}
  double U(double a, double b) { return std::uniform_real_distribution<double>(a, b)(g); }
  int I(int a, int b) { return std::uniform_int_distribution<int>(a, b)(g); }
};

cv::Mat LoadGray(const std::string& path) {
  cv::Mat m = cv::imread(path, cv::IMREAD_GRAYSCALE);
  Require(!m.empty(), ErrorCode::kIo, path + ": cannot read");
  return m;
}

// A large cluttered plane: rotated, scaled crops of the background photos and shapes.
cv::Mat MakeWorld(const std::vector<cv::Mat>& photos, Rng& r, cv::Size size) {
  cv::Mat world(size, CV_8UC1, cv::Scalar(r.U(60, 190)));
  for (int i = 0; i < 60; ++i) {
    const cv::Mat& p = photos[std::size_t(r.I(0, int(photos.size()) - 1))];
    const double s = r.U(0.4, 1.1), a = r.U(-180, 180);
    cv::Mat M = cv::getRotationMatrix2D(cv::Point2f(p.cols / 2.f, p.rows / 2.f), a, s);
    M.at<double>(0, 2) += r.U(0, size.width) - p.cols / 2.0;
    M.at<double>(1, 2) += r.U(0, size.height) - p.rows / 2.0;
    cv::Mat warped, mask;
    cv::warpAffine(p, warped, M, size, cv::INTER_AREA);
    cv::warpAffine(cv::Mat(p.size(), CV_8UC1, cv::Scalar(255)), mask, M, size, cv::INTER_NEAREST);
    warped.copyTo(world, mask);
  }
  for (int i = 0; i < 250; ++i) {
    const cv::Scalar col(r.U(0, 255));
    const cv::Point c(r.I(0, size.width - 1), r.I(0, size.height - 1));
    switch (r.I(0, 3)) {
      case 0: cv::circle(world, c, r.I(4, 40), col, r.I(0, 1) ? -1 : 2, cv::LINE_AA); break;
      case 1: cv::rectangle(world, c, c + cv::Point(r.I(-70, 70), r.I(-70, 70)), col, r.I(0, 1) ? -1 : 3, cv::LINE_AA); break;
      case 2: cv::line(world, c, c + cv::Point(r.I(-150, 150), r.I(-150, 150)), col, r.I(1, 5), cv::LINE_AA); break;
      default: cv::putText(world, std::to_string(r.I(10, 99999)), c, cv::FONT_HERSHEY_SIMPLEX, r.U(0.6, 2.5), col, 2, cv::LINE_AA);
    }
  }
  return world;
}

// Ground-truth homography (target pixels -> frame) from the clip's pose.
cv::Matx33d PoseH(cv::Size target, cv::Point2d centre, double zoom, double angle_deg, double tilt_x, double tilt_y) {
  const double w = target.width, h = target.height, a = angle_deg * CV_PI / 180;
  std::vector<cv::Point2f> src = {{0, 0}, {float(w), 0}, {float(w), float(h)}, {0, float(h)}}, dst;
  for (const auto& p : src) {
    const double x = p.x - w / 2, y = p.y - h / 2;
    double X = x * (1 + tilt_x * y / h), Y = y * (1 + tilt_y * x / w);
    const double rx = (X * std::cos(a) - Y * std::sin(a)) * zoom, ry = (X * std::sin(a) + Y * std::cos(a)) * zoom;
    dst.emplace_back(float(centre.x + rx), float(centre.y + ry));
  }
  return cv::Matx33d(cv::getPerspectiveTransform(src, dst));
}

struct Clip {
  std::vector<cv::Mat> frames;
  std::vector<cv::Matx33d> H;        // target -> frame
  std::vector<double> visible;       // fraction of the target's area inside the frame
  std::vector<bool> blurred;
  std::string target_id;
  cv::Size target_size;
};

double VisibleFraction(const cv::Matx33d& H, cv::Size target) {
  const auto q = ProjectOutline(H, target.width, target.height);
  std::vector<cv::Point2f> quad(q.begin(), q.end()), frame = {{0, 0}, {kW, 0}, {kW, kH}, {0, kH}}, inter;
  const double area = std::abs(cv::contourArea(quad));
  if (area <= 0) return 0;
  if (cv::contourArea(quad, true) < 0) std::reverse(quad.begin(), quad.end());
  const float a = cv::intersectConvexConvex(quad, frame, inter, true);
  return std::clamp(double(a) / area, 0.0, 1.0);
}

Clip MakeClip(const cv::Mat& target, const std::string& id, const std::vector<cv::Mat>& bg_photos, int n,
              std::uint64_t seed) {
  Rng r(seed);
  Clip c;
  c.target_id = id;
  c.target_size = target.size();
  const cv::Size world_size(2600, 1800);
  cv::Mat world = MakeWorld(bg_photos, r, world_size);
  // The target lies at the centre of the plane; T: target -> world.
  const cv::Matx33d T(1, 0, world_size.width / 2.0 - target.cols / 2.0, 0, 1, world_size.height / 2.0 - target.rows / 2.0,
                      0, 0, 1);
  const double ph[8] = {r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3), r.U(0, 6.3)};
  const double away_dir = r.I(0, 1) ? 1 : -1;
  // Out of view: pan away over [a0, a1), stay away until b0, come back by b1.
  const double a0 = 0.52, a1 = 0.57, b0 = 0.67, b1 = 0.72;
  for (int i = 0; i < n; ++i) {
    const double t = double(i) / std::max(1, n - 1);
    const double zoom = 1.0 + 0.5 * std::sin(2 * CV_PI * 1.3 * t + ph[0]);
    const double angle = 35 * std::sin(2 * CV_PI * 0.7 * t + ph[1]) + r.U(-0.4, 0.4);
    const double tx = 0.25 * std::sin(2 * CV_PI * 0.9 * t + ph[2]), ty = 0.2 * std::sin(2 * CV_PI * 0.6 * t + ph[3]);
    cv::Point2d centre(320 + 110 * std::sin(2 * CV_PI * 1.1 * t + ph[4]), 240 + 70 * std::sin(2 * CV_PI * 0.8 * t + ph[5]));
    // Hand shake: a few px of fast wobble plus jitter.
    centre += cv::Point2d(3 * std::sin(2 * CV_PI * 9 * t + ph[6]) + r.U(-1.5, 1.5),
                          3 * std::sin(2 * CV_PI * 11 * t + ph[7]) + r.U(-1.5, 1.5));
    double away = 0;  // 0..1: how far the camera has panned away
    if (t >= a0 && t < a1) away = 0.5 - 0.5 * std::cos(CV_PI * (t - a0) / (a1 - a0));
    else if (t >= a1 && t < b0) away = 1;
    else if (t >= b0 && t < b1) away = 0.5 + 0.5 * std::cos(CV_PI * (t - b0) / (b1 - b0));
    centre.x += away_dir * away * 1100;
    const cv::Matx33d H = PoseH(target.size(), centre, zoom, angle, tx, ty);
    // Camera: world -> frame = H * T^-1; the target drawn over it anti-aliased.
    cv::Mat frame, warped, mask;
    cv::warpPerspective(world, frame, cv::Mat(H * T.inv()), cv::Size(kW, kH), cv::INTER_LINEAR, cv::BORDER_REFLECT);
    WarpAntiAliased(target, H, frame.size(), warped, &mask);
    warped.copyTo(frame, mask);
    // Slow brightness / contrast drift, noise, sometimes motion blur.
    const double gain = 1 + 0.3 * std::sin(2 * CV_PI * 1.7 * t + ph[2]), offset = 25 * std::sin(2 * CV_PI * 1.2 * t + ph[5]);
    cv::Mat f;
    frame.convertTo(f, CV_32F, gain, offset);
    const bool blur = r.U(0, 1) < 0.12;
    if (blur) {
      const int len = r.I(5, 13);
      const double dir = r.U(0, CV_PI);
      cv::Mat k(len, len, CV_32F, cv::Scalar(0));
      const double c0 = (len - 1) / 2.0;
      cv::line(k, cv::Point2d(c0 - c0 * std::cos(dir), c0 - c0 * std::sin(dir)) * 1.0,
               cv::Point2d(c0 + c0 * std::cos(dir), c0 + c0 * std::sin(dir)), cv::Scalar(1), 1, cv::LINE_AA);
      k /= cv::sum(k)[0];
      cv::filter2D(f, f, -1, k, cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
    }
    cv::Mat noise(f.size(), CV_32F);
    cv::RNG cr(r.g());
    cr.fill(noise, cv::RNG::NORMAL, 0, 3);
    f += noise;
    f.convertTo(frame, CV_8UC1);
    c.frames.push_back(frame);
    c.H.push_back(H);
    c.visible.push_back(VisibleFraction(H, target.size()));
    c.blurred.push_back(blur);
  }
  return c;
}

struct ModeSpec {
  std::string name;
  FollowerOptions options;
};

struct Stats {
  std::vector<double> ms, err, jitter;
  int visible = 0, found = 0, after_first = 0, stays = 0, lost = 0, wrong = 0, absent = 0, false_pos = 0;
  int frames = 0, track_frames = 0, focus_frames = 0, full_frames = 0;
  void Add(const Stats& o) {
    ms.insert(ms.end(), o.ms.begin(), o.ms.end());
    err.insert(err.end(), o.err.begin(), o.err.end());
    jitter.insert(jitter.end(), o.jitter.begin(), o.jitter.end());
    visible += o.visible, found += o.found, after_first += o.after_first, stays += o.stays, lost += o.lost;
    wrong += o.wrong, absent += o.absent, false_pos += o.false_pos, frames += o.frames;
    track_frames += o.track_frames, focus_frames += o.focus_frames, full_frames += o.full_frames;
  }
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(std::ceil(q * double(v.size()))) - (q > 0 ? 1 : 0))];
}
double Median(const std::vector<double>& v) { return Percentile(v, 0.5); }
double Mean(const std::vector<double>& v) {
  return v.empty() ? 0 : std::accumulate(v.begin(), v.end(), 0.0) / double(v.size());
}

Stats Run(const Recognizer& rec, const std::map<std::string, cv::Size>& sizes, const Clip& clip, const ModeSpec& m,
          double max_err) {
  VideoFollower f(rec, m.options);
  for (const auto& [id, s] : sizes) f.SetObjectSize(id, s);
  Stats st;
  bool seen = false, prev_ok = false, have_prev_vis = false;
  std::array<cv::Point2d, 4> prev_e{};
  bool prev_correct = false;
  for (std::size_t i = 0; i < clip.frames.size(); ++i) {
    const FollowedFrame r = f.Process(clip.frames[i]);
    ++st.frames;
    st.ms.push_back(r.ms);
    st.track_frames += r.mode == FrameMode::kTrack;
    st.focus_frames += r.mode == FrameMode::kFocus;
    st.full_frames += r.mode == FrameMode::kFull;
    const double vis = clip.visible[i];
    bool correct = false;
    std::array<cv::Point2d, 4> e{};
    double err = 0;
    int others = 0;
    for (const auto& x : r.found) {
      if (x.id == clip.target_id && !correct) {
        err = MeanCornerError(x.homography, clip.H[i], clip.target_size);
        if (err < max_err) {
          correct = true;
          const auto a = ProjectOutline(x.homography, clip.target_size.width, clip.target_size.height);
          const auto b = ProjectOutline(clip.H[i], clip.target_size.width, clip.target_size.height);
          for (int k = 0; k < 4; ++k) e[std::size_t(k)] = cv::Point2d(a[std::size_t(k)] - b[std::size_t(k)]);
          continue;
        }
      }
      ++others;
    }
    if (vis <= 0) {
      ++st.absent;
      st.false_pos += !r.found.empty();
    } else {
      st.wrong += others > 0;
      if (others > 0 && std::getenv("MVKP_BENCH_DEBUG"))
        std::fprintf(stderr, "%s frame %zu vis %.2f mode %s err %.1f tracked %d blur %d\n", m.name.c_str(), i, vis,
                     FrameModeName(r.mode), err, int(r.tracked), int(clip.blurred[i]));
    }
    if (correct) {
      st.err.push_back(err);
      if (prev_correct) {
        double j = 0;
        for (int k = 0; k < 4; ++k) j += cv::norm(e[std::size_t(k)] - prev_e[std::size_t(k)]);
        st.jitter.push_back(j / 4);
      }
    }
    prev_correct = correct;
    prev_e = e;
    if (vis >= 0.5) {
      ++st.visible;
      st.found += correct;
      if (correct && !seen) seen = true;
      if (seen) {
        ++st.after_first;
        st.stays += correct;
        if (have_prev_vis && prev_ok && !correct) ++st.lost;
      }
      have_prev_vis = true;
      prev_ok = correct;
    }
  }
  return st;
}

nlohmann::json ToJson(const Stats& s) {
  return {{"frames", s.frames},
          {"ms", {{"median", Median(s.ms)}, {"mean", Mean(s.ms)}, {"p95", Percentile(s.ms, 0.95)}, {"max", Percentile(s.ms, 1.0)}}},
          {"visible_frames", s.visible},
          {"found_rate", s.visible ? double(s.found) / s.visible : 0},
          {"stays_found_rate", s.after_first ? double(s.stays) / s.after_first : 0},
          {"lost_events", s.lost},
          {"corner_error_px", {{"mean", Mean(s.err)}, {"median", Median(s.err)}, {"p95", Percentile(s.err, 0.95)}}},
          {"jitter_px", Mean(s.jitter)},
          {"wrong_frames", s.wrong},
          {"absent_frames", s.absent},
          {"false_detections", s.false_pos},
          {"modes", {{"full", s.full_frames}, {"focus", s.focus_frames}, {"track", s.track_frames}}}};
}

void PrintRow(const std::string& name, const Stats& s) {
  std::printf("%-10s | %6.2f %6.2f %6.2f | %6.1f%% %6.1f%% %4d | %5.2f %5.2f %6.3f | %4d %4d/%-4d | %4d %4d %4d\n",
              name.c_str(), Median(s.ms), Mean(s.ms), Percentile(s.ms, 0.95),
              s.visible ? 100.0 * s.found / s.visible : 0, s.after_first ? 100.0 * s.stays / s.after_first : 0, s.lost,
              Mean(s.err), Percentile(s.err, 0.95), Mean(s.jitter), s.wrong, s.false_pos, s.absent, s.full_frames,
              s.focus_frames, s.track_frames);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Following a target through video: full search, temporal focus, focus + KLT tracking (issue 6)"};
  int videos = 3, frames = 300, threads = 1, lose_after = 3, views = 100;
  std::uint64_t seed = 1;
  double max_err = 10;
  FollowerOptions fo_base;
  std::vector<std::string> modes = {"full", "focus", "klt"};
  std::vector<int> redetect = {TrackerOptions{}.redetect_every};
  std::vector<std::string> target_names = {"starry_night", "astronaut", "building"};
  std::vector<std::string> bg_names = {"fruits", "baboon", "coffee"};
  std::string samples = std::string(MVKP_SOURCE_DIR) + "/samples", json_out, dump_dir;
  bool per_video = false;
  app.add_option("--videos", videos, "clips")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option("--frames", frames, "frames per clip")->capture_default_str()->check(CLI::Range(20, 100000));
  app.add_option("--seed", seed, "drives the clips")->capture_default_str();
  app.add_option("--modes", modes, "full | focus | klt")->delimiter(',')->check(CLI::IsMember({"full", "focus", "klt"}))
      ->capture_default_str();
  app.add_option("--redetect-every", redetect, "klt: recogniser checks every N frames (several: one row each)")
      ->delimiter(',')->capture_default_str();
  app.add_option("--agree-px", fo_base.agree_px, "klt: detection within this of the tracker keeps the tracker's pose")
      ->capture_default_str();
  app.add_option("--track-window", fo_base.tracker.window, "klt: LK window")->capture_default_str();
  app.add_option("--track-points", fo_base.tracker.max_points, "klt: points tracked")->capture_default_str();
  app.add_option("--lose-after", lose_after, "misses of the focused target before the full search")->capture_default_str();
  app.add_option("--targets", target_names, "sample photos (stems) used as targets")->delimiter(',')->capture_default_str();
  app.add_option("--backgrounds", bg_names, "sample photos (stems) the clutter is made of")->delimiter(',')->capture_default_str();
  app.add_option("--samples", samples, "directory of the sample photos")->capture_default_str();
  app.add_option("--views", views, "TrainOptions::views")->capture_default_str();
  app.add_option("--max-corner-error", max_err, "px, for a correct detection")->capture_default_str();
  app.add_option("--threads", threads, "cv::setNumThreads")->capture_default_str();
  app.add_flag("--per-video", per_video, "also print each clip's rows");
  app.add_option("--json", json_out, "write the results as JSON");
  app.add_option("--dump", dump_dir, "write every 10th frame of each clip here (PNG)");
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(threads);

  try {
    std::vector<cv::Mat> bg;
    for (const auto& n : bg_names) bg.push_back(LoadGray(samples + "/" + n + ".jpg"));
    TrainOptions to;  // `mvkp db add` settings
    to.max_object_side = 320;
    to.min_scale = 0.25;
    to.views = views;
    to.seed = seed;
    Recognizer rec;
    std::map<std::string, cv::Size> sizes;
    std::vector<cv::Mat> targets;
    const auto t0 = std::chrono::steady_clock::now();
    for (const auto& n : target_names) {
      cv::Mat t = PrepareTarget(LoadGray(samples + "/" + n + ".jpg"), 320);
      const Model m = Train(t, to);
      rec.Add(n, m);
      sizes[n] = cv::Size(m.object_width, m.object_height);
      targets.push_back(t);
    }
    const double train_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    std::vector<ModeSpec> specs;
    for (const auto& m : modes) {
      if (m == "klt") {
        for (int n : redetect) {
          ModeSpec s{redetect.size() > 1 ? "klt/" + std::to_string(n) : "klt", fo_base};
          s.options.track = true;
          s.options.tracker.redetect_every = n;
          s.options.lose_after = lose_after;
          specs.push_back(s);
        }
      } else {
        ModeSpec s{m, {}};
        s.options.track = false;
        s.options.focus = m == "focus";
        s.options.lose_after = lose_after;
        specs.push_back(s);
      }
    }
    for (auto& s : specs) s.options.Check();

    std::printf("%d clips x %d frames, 640x480, %zu targets (trained in %.1f s), seed %llu, %d thread(s), "
                "correct: corner error < %.0f px\n",
                videos, frames, targets.size(), train_s, (unsigned long long)seed, threads, max_err);
    const char* header =
        "%-10s | %6s %6s %6s | %7s %7s %4s | %5s %5s %6s | %4s %9s | %4s %4s %4s\n";
    std::printf(header, "mode", "med_ms", "mean", "p95", "found", "stays", "lost", "err", "err95", "jitter", "wrong",
                "falseP/abs", "full", "focus", "track");
    std::vector<Stats> total(specs.size());
    nlohmann::json jclips = nlohmann::json::array();
    for (int v = 0; v < videos; ++v) {
      const std::size_t ti = std::size_t(v) % targets.size();
      const Clip clip = MakeClip(targets[ti], target_names[ti], bg, frames, seed * 1000003 + std::uint64_t(v));
      if (!dump_dir.empty()) {
        std::filesystem::create_directories(dump_dir);
        for (std::size_t i = 0; i < clip.frames.size(); i += 10)
          cv::imwrite(dump_dir + "/clip" + std::to_string(v) + "_" + std::to_string(i) + ".png", clip.frames[i]);
      }
      int vis = 0, absent = 0, blurred = 0;
      for (std::size_t i = 0; i < clip.frames.size(); ++i) {
        vis += clip.visible[i] >= 0.5;
        absent += clip.visible[i] <= 0;
        blurred += clip.blurred[i];
      }
      nlohmann::json jc = {{"clip", v}, {"target", clip.target_id}, {"visible_frames", vis}, {"absent_frames", absent},
                           {"blurred_frames", blurred}, {"modes", nlohmann::json::object()}};
      if (per_video)
        std::printf("-- clip %d: %s, %d visible, %d out of view, %d motion-blurred\n", v, clip.target_id.c_str(), vis,
                    absent, blurred);
      for (std::size_t k = 0; k < specs.size(); ++k) {
        const Stats s = Run(rec, sizes, clip, specs[k], max_err);
        if (per_video) PrintRow(specs[k].name, s);
        jc["modes"][specs[k].name] = ToJson(s);
        total[k].Add(s);
      }
      jclips.push_back(jc);
    }
    if (per_video) std::printf("-- all clips\n");
    nlohmann::json jmodes = nlohmann::json::object();
    for (std::size_t k = 0; k < specs.size(); ++k) {
      PrintRow(specs[k].name, total[k]);
      jmodes[specs[k].name] = ToJson(total[k]);
    }
    if (!json_out.empty()) {
      nlohmann::json j = {{"settings",
                           {{"videos", videos}, {"frames", frames}, {"seed", seed}, {"threads", threads},
                            {"lose_after", lose_after}, {"redetect_every", redetect}, {"agree_px", fo_base.agree_px},
                            {"track_window", fo_base.tracker.window}, {"track_points", fo_base.tracker.max_points}, {"targets", target_names},
                            {"backgrounds", bg_names}, {"views", views}, {"max_corner_error", max_err},
                            {"train_s", train_s}}},
                          {"modes", jmodes},
                          {"clips", jclips}};
      std::ofstream(json_out) << j.dump(2) << "\n";
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
