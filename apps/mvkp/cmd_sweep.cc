// mvkp eval sweep: the envelope benchmark. Camera-model views of real targets
// (a pinhole camera, the target plane at a tilt from any azimuth, any roll, at
// the distance that makes its longest side S pixels, over a crop of a real
// photo, with lighting, blur, noise and JPEG; synth/camera_view.h), band by
// band over apparent size and tilt, scored for mvkp and OpenCV SIFT, ORB and
// ASIFT (AffineFeature over SIFT) on the same frames in the same run. Writes
// a CSV row per frame and method, a summary (Markdown and JSON) and two SVG
// curves: ok@5px against apparent size and against tilt.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "baselines.h"
#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/match/matcher.h"
#include "mvkp/model/model.h"
#include "mvkp/synth/camera_view.h"
#include "mvkp/train/trainer.h"
#include "output.h"
#include "svg_plot.h"

namespace mvkp::cli {
namespace {

namespace fs = std::filesystem;

struct Range {
  double lo = 0, hi = 0;
  std::string Name(int decimals = 0) const {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f-%.*f", decimals, lo, decimals, hi);
    return b;
  }
};

struct SweepArgs {
  std::vector<std::string> targets, backgrounds;
  std::string out = "out/sweep";
  std::vector<std::string> methods = {"mvkp", "sift", "orb", "asift"};
  std::vector<double> size_edges = {40, 60, 80, 110, 150, 200, 280, 400, 510, 620};
  std::string size_tilt = "0-40";
  std::vector<double> tilt_edges = {0, 20, 40, 50, 60, 67.5, 75, 80};
  std::string tilt_size = "200-400";
  std::vector<std::string> table_sizes = {"60-110", "110-200", "200-400", "400-620"};
  std::vector<std::string> table_tilts = {"0-40", "40-60", "60-75", "75-80"};
  int per_target = 4;
  std::uint64_t seed = 1;
  double asift_min_tilt = 40;
  int width = 640, height = 480;
  bool save_frames = false;
  bool diagnose = false;
  std::string label;
  CameraSceneOptions scene;
  TrainOptions train;
  MatchOptions match;
  bool affine = false;
};

Range ParseRange(const std::string& s, const char* what) {
  Range r;
  char dash = 0;
  std::istringstream in(s);
  if (!(in >> r.lo >> dash >> r.hi) || dash != '-' || !in.eof() || !(r.lo <= r.hi))
    throw Error(ErrorCode::kInvalidArgument, std::string(what) + ": expected LO-HI with LO <= HI, got '" + s + "'");
  return r;
}

struct Frame {
  std::string target, family, bin;
  int target_index = 0;
  CameraPose pose;
  bool inside = true;
};

struct Outcome {
  std::string method;
  bool ran = false, found = false;
  double err = INFINITY, ms = 0;
  int inliers = 0, keypoints = 0, support = 0;
  int matches = -1, correct = -1, on_target = -1, repeat = -1, nn_ok = -1;
  double hull = -1;  // mvkp: share of the target's area inside the convex hull of the inliers' object points  // ratio-test matches, those within 5 px of the truth, query points on the target
  MatchTiming split;
};

// Geometric checks of the bands (before any work is done).
void CheckBands(const SweepArgs& a, const Range& size_tilt, const Range& tilt_size) {
  const double frame_side = std::max(a.width, a.height);
  auto size_ok = [&](double s, const std::string& where) {
    Require(s >= 8, ErrorCode::kInvalidArgument, where + ": apparent sizes must be >= 8 px, got " + std::to_string(s));
    Require(s <= frame_side, ErrorCode::kInvalidArgument,
            where + ": apparent size " + std::to_string(int(s)) + " px is bigger than the " + std::to_string(a.width) +
                "x" + std::to_string(a.height) + " frame");
  };
  auto tilt_ok = [&](double t, const std::string& where) {
    Require(t >= 0 && t < 90, ErrorCode::kInvalidArgument,
            where + ": tilts must be in [0, 90) degrees (a plane at 90 degrees is seen edge-on), got " + std::to_string(t));
    Require(t <= 89, ErrorCode::kInvalidArgument, where + ": tilts above 89 degrees leave no image of the target");
  };
  auto edges_ok = [&](const std::vector<double>& e, const char* what) {
    Require(e.size() >= 2, ErrorCode::kInvalidArgument, std::string(what) + ": need at least two edges");
    for (std::size_t i = 1; i < e.size(); ++i)
      Require(e[i] > e[i - 1], ErrorCode::kInvalidArgument, std::string(what) + ": edges must increase");
  };
  edges_ok(a.size_edges, "--size-edges");
  edges_ok(a.tilt_edges, "--tilt-edges");
  for (double s : a.size_edges) size_ok(s, "--size-edges");
  for (double t : a.tilt_edges) tilt_ok(t, "--tilt-edges");
  size_ok(tilt_size.lo, "--tilt-size");
  size_ok(tilt_size.hi, "--tilt-size");
  tilt_ok(size_tilt.lo, "--size-tilt");
  tilt_ok(size_tilt.hi, "--size-tilt");
  for (const auto& s : a.table_sizes) {
    const Range r = ParseRange(s, "--table-sizes");
    size_ok(r.hi, "--table-sizes");
  }
  for (const auto& s : a.table_tilts) tilt_ok(ParseRange(s, "--table-tilts").hi, "--table-tilts");
  Require(a.per_target >= 1 && a.per_target <= 10000, ErrorCode::kInvalidArgument, "--per-target must be in 1..10000");
  for (const auto& m : a.methods)
    Require(m == "mvkp" || m == "sift" || m == "orb" || m == "asift" || m == "akaze", ErrorCode::kInvalidArgument,
            "--methods: unknown method '" + m + "' (mvkp, sift, orb, asift, akaze)");
}

std::vector<Frame> PlanFrames(const SweepArgs& a, const Range& size_tilt, const Range& tilt_size) {
  std::mt19937_64 rng(a.seed * 0x9E3779B97F4A7C15ull + 17);
  auto U = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto LogU = [&](double lo, double hi) { return std::exp(U(std::log(lo), std::log(hi))); };
  std::vector<Frame> frames;
  for (int t = 0; t < int(a.targets.size()); ++t) {
    for (std::size_t b = 0; b + 1 < a.size_edges.size(); ++b)
      for (int k = 0; k < a.per_target; ++k) {
        Frame f;
        f.target = a.targets[t];
        f.target_index = t;
        f.family = "size";
        f.bin = Range{a.size_edges[b], a.size_edges[b + 1]}.Name();
        f.pose.size_px = LogU(a.size_edges[b], a.size_edges[b + 1]);
        f.pose.tilt_deg = U(size_tilt.lo, size_tilt.hi);
        f.pose.azimuth_deg = U(0, 360);
        f.pose.roll_deg = U(0, 360);
        frames.push_back(f);
      }
    for (std::size_t b = 0; b + 1 < a.tilt_edges.size(); ++b)
      for (int k = 0; k < a.per_target; ++k) {
        Frame f;
        f.target = a.targets[t];
        f.target_index = t;
        f.family = "tilt";
        f.bin = Range{a.tilt_edges[b], a.tilt_edges[b + 1]}.Name(1);
        f.pose.size_px = LogU(tilt_size.lo, tilt_size.hi);
        f.pose.tilt_deg = U(a.tilt_edges[b], a.tilt_edges[b + 1]);
        f.pose.azimuth_deg = U(0, 360);
        f.pose.roll_deg = U(0, 360);
        frames.push_back(f);
      }
  }
  return frames;
}

struct Method {
  std::string name;
  std::unique_ptr<Matcher> mvkp;
  std::unique_ptr<Baseline> base;
};

std::string Csv(double v) {
  if (!std::isfinite(v)) return "";
  char b[32];
  std::snprintf(b, sizeof b, "%.3f", v);
  return b;
}

int RunSweep(SweepArgs& a) {
  if (a.affine) a.match.geometry = GeometryModel::kAffine;
  const Range size_tilt = ParseRange(a.size_tilt, "--size-tilt"), tilt_size = ParseRange(a.tilt_size, "--tilt-size");
  a.scene.width = a.width;
  a.scene.height = a.height;
  a.scene.Check();
  CheckBands(a, size_tilt, tilt_size);
  Require(!a.targets.empty(), ErrorCode::kInvalidArgument, "no targets");
  Require(!a.backgrounds.empty(), ErrorCode::kInvalidArgument, "no --background photos (real photos of streets, rooms, tables)");

  std::vector<cv::Mat> backgrounds;
  for (const auto& b : a.backgrounds) backgrounds.push_back(LoadImageColor(b));
  fs::create_directories(a.out);
  if (a.save_frames) fs::create_directories(fs::path(a.out) / "frames");

  // Per target: the colour image (rendered), its grey version (trained on),
  // the trained model and the baselines prepared once.
  struct Target {
    std::string path, name;
    cv::Mat colour, gray;
    std::vector<Method> methods;
    double train_ms = 0;
    std::size_t model_bytes = 0;
    int locations = 0, centres = 0;
  };
  std::deque<Target> targets;  // never relocated (holds matchers)
  for (const auto& p : a.targets) {
    Target t;
    t.path = p;
    t.name = fs::path(p).stem().string();
    t.colour = LoadImageColor(p);
    cv::cvtColor(t.colour, t.gray, cv::COLOR_BGR2GRAY);
    for (const auto& m : a.methods) {
      Method me;
      me.name = m;
      if (m == "mvkp") {
        Timer tt;
        Model model = TrainNamed(p, t.gray, a.train);
        t.train_ms = tt.ElapsedMs();
        t.model_bytes = SerializeModel(model).size();
        t.locations = int(model.locations.size());
        t.centres = model.descriptors.rows;
        me.mvkp = std::make_unique<Matcher>(model, a.match);
      } else {
        me.base = std::make_unique<Baseline>(m);
        me.base->Prepare(t.gray);
      }
      t.methods.push_back(std::move(me));
    }
    std::fprintf(stderr, "sweep: %s %dx%d", t.name.c_str(), t.gray.cols, t.gray.rows);
    if (t.centres) std::fprintf(stderr, ", trained in %.0f ms, %d locations, %d centres, %zu KB", t.train_ms, t.locations, t.centres, t.model_bytes / 1024);
    std::fprintf(stderr, "\n");
    targets.push_back(std::move(t));
  }

  std::vector<Frame> frames = PlanFrames(a, size_tilt, tilt_size);
  std::ofstream csv(fs::path(a.out) / "sweep.csv");
  Require(bool(csv), ErrorCode::kIo, a.out + "/sweep.csv: cannot write");
  csv << "frame,target,family,bin,size_px,tilt_deg,azimuth_deg,roll_deg,hfov_deg,inside,method,found,corner_err,ok5,ms,"
         "detect_ms,describe_ms,search_ms,verify_ms,inliers,keypoints,matches,correct,on_target,support,repeat,nn_ok,inlier_hull\n";
  std::ofstream manifest;
  if (a.save_frames) manifest.open(fs::path(a.out) / "frames" / "manifest.txt");
  std::vector<std::vector<Outcome>> results(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    Frame& f = frames[i];
    Target& t = targets[f.target_index];
    const std::uint64_t seed = a.seed * 1000003ull + i;
    const cv::Mat& bg = backgrounds[(seed * 2654435761ull >> 7) % backgrounds.size()];
    const CameraScene s = MakeCameraScene(t.colour, bg, f.pose, a.scene, seed);
    f.pose = s.pose;
    f.inside = s.inside;
    cv::Mat gray;
    cv::cvtColor(s.image, gray, cv::COLOR_BGR2GRAY);
    if (a.save_frames) {
      char name[64];
      std::snprintf(name, sizeof name, "frame_%05zu", i);
      cv::imwrite((fs::path(a.out) / "frames" / (std::string(name) + ".png")).string(), s.image);
      std::ofstream h(fs::path(a.out) / "frames" / (std::string(name) + ".H"));
      h.precision(17);
      for (int r = 0; r < 3; ++r) h << s.H(r, 0) << " " << s.H(r, 1) << " " << s.H(r, 2) << "\n";
      manifest << fs::absolute(t.path).string() << " " << name << ".png " << name << ".H\n";
    }
    for (auto& m : t.methods) {
      Outcome o;
      o.method = m.name;
      if (m.name == "asift" && f.pose.tilt_deg < a.asift_min_tilt) {
        results[i].push_back(o);
        continue;
      }
      o.ran = true;
      if (m.mvkp) {
        const MatchResult r = m.mvkp->Match(gray);
        o.found = r.found;
        o.ms = r.time.total();
        o.split = r.time;
        o.inliers = r.inliers;
        o.support = r.support;
        o.keypoints = r.keypoints;
        if (r.found) {
          o.err = MeanCornerError(r.homography, s.H, t.gray.size());
          std::vector<cv::Point2f> pts, hull;
          for (const auto& mm : r.matches)
            if (mm.inlier) pts.push_back(mm.object);
          if (pts.size() >= 3) {
            cv::convexHull(pts, hull);
            o.hull = cv::contourArea(hull) / double(t.gray.cols * t.gray.rows);
          }
        }
        o.matches = int(r.matches.size());
        o.correct = 0;
        for (const auto& mm : r.matches) {
          const cv::Vec3d p = s.H * cv::Vec3d(mm.object.x, mm.object.y, 1);
          o.correct += cv::norm(cv::Point2d(p[0] / p[2], p[1] / p[2]) - cv::Point2d(mm.query)) < 5;
        }
        if (a.diagnose) {
          const Features ff = ExtractFeatures(gray, QueryFeatureOptions(m.mvkp->model().params, a.match.max_points));
          const auto qa = OutlineUnder(s.H, t.gray.size());
          std::vector<cv::Point2f> poly;
          for (const auto& c : qa) poly.emplace_back(float(c.x), float(c.y));
          o.on_target = 0;
          for (const auto& k : ff.keypoints) o.on_target += cv::pointPolygonTest(poly, {k.x, k.y}, false) > 0;
          // Repeatability: query points within 3 px of where the truth puts
          // a model location; of those, how many have their nearest centre
          // (brute force) at a location the truth puts within 5 px.
          const Model& mo = m.mvkp->model();
          std::vector<cv::Point2f> proj;
          for (const auto& l : mo.locations) {
            const cv::Vec3d p = s.H * cv::Vec3d(l.x, l.y, 1);
            proj.emplace_back(float(p[0] / p[2]), float(p[1] / p[2]));
          }
          o.repeat = 0;
          o.nn_ok = 0;
          for (int qi = 0; qi < int(ff.keypoints.size()); ++qi) {
            const cv::Point2f kp(ff.keypoints[qi].x, ff.keypoints[qi].y);
            bool rep = false;
            for (const auto& pp : proj) rep |= cv::norm(pp - kp) < 3;
            if (!rep) continue;
            ++o.repeat;
            int best = -1;
            float bd = 1e30f;
            for (int ci = 0; ci < mo.descriptors.rows; ++ci) {
              float d = 0;
              for (int k = 0; k < mo.descriptors.cols; ++k) {
                const float t = mo.descriptors.at<float>(ci, k) - ff.descriptors.at<float>(qi, k);
                d += t * t;
              }
              if (d < bd) { bd = d; best = ci; }
            }
            if (best >= 0 && cv::norm(proj[mo.labels[best]] - kp) < 5) ++o.nn_ok;
          }
        }
      } else {
        const BaselineResult r = m.base->Frame(gray);
        o.found = r.found;
        o.ms = r.ms;
        o.inliers = int(std::count(r.inlier.begin(), r.inlier.end(), 1));
        o.keypoints = r.keypoints;
        if (r.found) o.err = MeanCornerError(r.homography, s.H, t.gray.size());
      }
      csv << i << "," << t.name << "," << f.family << "," << f.bin << "," << Csv(f.pose.size_px) << ","
          << Csv(f.pose.tilt_deg) << "," << Csv(f.pose.azimuth_deg) << "," << Csv(f.pose.roll_deg) << ","
          << Csv(f.pose.hfov_deg) << "," << int(f.inside) << "," << o.method << "," << int(o.found) << ","
          << Csv(o.err) << "," << int(o.err < 5) << "," << Csv(o.ms) << ",";
      if (m.mvkp)
        csv << Csv(o.split.smooth_ms + o.split.detect_ms) << "," << Csv(o.split.describe_ms) << ","
            << Csv(o.split.search_ms) << "," << Csv(o.split.verify_ms);
      else
        csv << ",,,";
      csv << "," << o.inliers << "," << o.keypoints << "," << o.matches << "," << o.correct << "," << o.on_target << "," << o.support << "," << o.repeat << "," << o.nn_ok << "," << (o.hull >= 0 ? Csv(o.hull) : "") << "\n";
      results[i].push_back(o);
    }
    Progress("sweep: frame", int(i + 1), int(frames.size()));
  }
  csv.close();

  // ---- summary: table bands and curve bins
  struct Cell {
    int n = 0, ok5 = 0, ok10 = 0;
    std::vector<double> ms, det, desc, search, verify;
    void Add(const Outcome& o) {
      ++n;
      ok5 += o.err < 5;
      ok10 += o.err < 10;
      ms.push_back(o.ms);
      if (o.method == "mvkp") {
        det.push_back(o.split.smooth_ms + o.split.detect_ms);
        desc.push_back(o.split.describe_ms);
        search.push_back(o.split.search_ms);
        verify.push_back(o.split.verify_ms);
      }
    }
  };
  auto collect = [&](const std::string& family, const Range& r, bool by_size) {
    std::map<std::string, Cell> cells;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const Frame& f = frames[i];
      if (f.family != family) continue;
      const double v = by_size ? f.pose.size_px : f.pose.tilt_deg;
      if (v < r.lo || v >= r.hi) continue;
      for (const auto& o : results[i])
        if (o.ran) cells[o.method].Add(o);
    }
    return cells;
  };
  nlohmann::json summary;
  summary["label"] = a.label;
  summary["frame"] = {a.width, a.height};
  summary["per_target"] = a.per_target;
  summary["seed"] = a.seed;
  for (const auto& t : targets)
    summary["targets"].push_back({{"name", t.name}, {"width", t.gray.cols}, {"height", t.gray.rows},
                                  {"train_ms", t.train_ms}, {"model_bytes", t.model_bytes},
                                  {"locations", t.locations}, {"centres", t.centres}});
  std::ostringstream md;
  md << "# mvkp eval sweep" << (a.label.empty() ? "" : ": " + a.label) << "\n\n"
     << targets.size() << " targets, " << a.per_target << " frames per target and bin, " << a.width << "x" << a.height
     << ", seed " << a.seed << ", one thread\n\n";
  md << "| band (longest side px, tilt deg) | frames |";
  for (const auto& m : a.methods) md << " " << m << " ok@5px |";
  for (const auto& m : a.methods) md << " " << m << " ms |";
  md << " mvkp detect / describe / search / verify ms |\n|---|---|";
  for (std::size_t k = 0; k < 2 * a.methods.size() + 1; ++k) md << "---|";
  md << "\n";
  auto table_row = [&](const std::string& label, const std::map<std::string, Cell>& cells) {
    int n = 0;
    for (const auto& [m, c] : cells) n = std::max(n, c.n);
    md << "| " << label << " | " << n << " |";
    nlohmann::json row = {{"band", label}, {"frames", n}};
    for (const auto& m : a.methods) {
      auto it = cells.find(m);
      if (it == cells.end() || it->second.n == 0) {
        md << " — |";
        continue;
      }
      char b[32];
      std::snprintf(b, sizeof b, " %.2f |", double(it->second.ok5) / it->second.n);
      md << b;
      row[m] = {{"n", it->second.n}, {"ok5", double(it->second.ok5) / it->second.n},
                {"ok10", double(it->second.ok10) / it->second.n}, {"median_ms", Median(it->second.ms)}};
    }
    for (const auto& m : a.methods) {
      auto it = cells.find(m);
      if (it == cells.end() || it->second.n == 0) {
        md << " — |";
        continue;
      }
      char b[32];
      std::snprintf(b, sizeof b, " %.1f |", Median(it->second.ms));
      md << b;
    }
    auto it = cells.find("mvkp");
    if (it != cells.end() && it->second.n) {
      char b[96];
      std::snprintf(b, sizeof b, " %.2f / %.2f / %.2f / %.2f |", Median(it->second.det), Median(it->second.desc),
                    Median(it->second.search), Median(it->second.verify));
      md << b;
      row["mvkp_split_ms"] = {{"detect", Median(it->second.det)}, {"describe", Median(it->second.desc)},
                              {"search", Median(it->second.search)}, {"verify", Median(it->second.verify)}};
    } else {
      md << " — |";
    }
    md << "\n";
    return row;
  };
  for (const auto& s : a.table_sizes) {
    const Range r = ParseRange(s, "--table-sizes");
    summary["table"].push_back(table_row(r.Name() + " px, " + size_tilt.Name() + "°", collect("size", r, true)));
  }
  for (const auto& s : a.table_tilts) {
    const Range r = ParseRange(s, "--table-tilts");
    summary["table"].push_back(table_row(tilt_size.Name() + " px, " + r.Name() + "°", collect("tilt", r, false)));
  }
  // All frames together: the per-frame time a user sees.
  {
    std::map<std::string, Cell> all;
    for (std::size_t i = 0; i < frames.size(); ++i)
      for (const auto& o : results[i])
        if (o.ran) all[o.method].Add(o);
    summary["all"] = table_row("all frames", all);
  }
  md << "\nTraining: ";
  std::vector<double> tms, kb;
  for (const auto& t : targets)
    if (t.centres) {
      tms.push_back(t.train_ms);
      kb.push_back(t.model_bytes / 1024.0);
    }
  if (!tms.empty()) {
    char b[160];
    std::snprintf(b, sizeof b, "median %.0f ms (max %.0f), model median %.0f KB (max %.0f)\n", Median(tms),
                  *std::max_element(tms.begin(), tms.end()), Median(kb), *std::max_element(kb.begin(), kb.end()));
    md << b;
  } else {
    md << "(mvkp not run)\n";
  }

  // ---- curves
  auto curve = [&](const std::string& family, const std::vector<double>& edges, bool by_size, const std::string& xlabel,
                   const std::string& title, const std::string& file) {
    LineChart c;
    c.title = title;
    c.subtitle = std::to_string(targets.size()) + " targets, " + std::to_string(a.per_target) +
                 " camera-model frames per target and bin, " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                 (a.label.empty() ? "" : " (" + a.label + ")");
    c.xlabel = xlabel;
    c.ylabel = "ok@5px (share of frames, corner error < 5 px)";
    c.ymin = 0;
    c.ymax = 1;
    nlohmann::json js;
    for (const auto& m : a.methods) {
      Series s;
      s.name = m;
      for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
        const Range r{edges[b], edges[b + 1]};
        const auto cells = collect(family, r, by_size);
        auto it = cells.find(m);
        const double x = by_size ? std::sqrt(r.lo * r.hi) : 0.5 * (r.lo + r.hi);
        if (it == cells.end() || it->second.n == 0) continue;
        s.x.push_back(x);
        s.y.push_back(double(it->second.ok5) / it->second.n);
        js[m].push_back({{"bin", r.Name(by_size ? 0 : 1)}, {"x", x}, {"ok5", s.y.back()}, {"n", it->second.n}});
      }
      c.series.push_back(s);
    }
    WriteTextFile((fs::path(a.out) / file).string(), RenderLineChart(c));
    summary["curves"][family] = js;
  };
  curve("size", a.size_edges, true, "apparent size: longest side in the frame (px)",
        "ok@5px against apparent size (tilt " + size_tilt.Name() + "°)", "size.svg");
  curve("tilt", a.tilt_edges, false, "tilt of the target plane (degrees)",
        "ok@5px against tilt (longest side " + tilt_size.Name() + " px)", "tilt.svg");

  std::ofstream(fs::path(a.out) / "summary.md") << md.str();
  std::ofstream(fs::path(a.out) / "summary.json") << summary.dump(1) << "\n";
  std::printf("%s", md.str().c_str());
  std::printf("\nwrote %s/{sweep.csv,summary.md,summary.json,size.svg,tilt.svg}\n", a.out.c_str());
  return 0;
}

}  // namespace

void RegisterEvalSweep(CLI::App* eval, int* code) {
  auto a = std::make_shared<SweepArgs>();
  auto* c = eval->add_subcommand(
      "sweep", "Envelope benchmark: camera-model views band by band (apparent size, tilt); mvkp, SIFT, ORB, ASIFT");
  c->add_option("TARGET", a->targets, "target images (paintings, covers, posters)")->required();
  c->add_option("--background", a->backgrounds, "real photos to put the targets in (streets, rooms, tables)")->required();
  c->add_option("-o,--output", a->out, "report folder")->capture_default_str();
  c->add_option("--methods", a->methods, "mvkp sift orb asift akaze")->delimiter(',')->capture_default_str();
  c->add_option("--per-target", a->per_target, "frames per target and bin")->capture_default_str();
  c->add_option("--frame-seed", a->seed, "seed of the poses and frames (--seed is the training seed)")->capture_default_str();
  c->add_option("--size-edges", a->size_edges, "bin edges of apparent size (longest side, px)")->delimiter(',');
  c->add_option("--size-tilt", a->size_tilt, "tilt range of the size bins (degrees, LO-HI)")->capture_default_str();
  c->add_option("--tilt-edges", a->tilt_edges, "bin edges of tilt (degrees)")->delimiter(',');
  c->add_option("--tilt-size", a->tilt_size, "apparent size range of the tilt bins (px, LO-HI)")->capture_default_str();
  c->add_option("--table-sizes", a->table_sizes, "size bands of the table")->delimiter(',');
  c->add_option("--table-tilts", a->table_tilts, "tilt bands of the table")->delimiter(',');
  c->add_option("--asift-min-tilt", a->asift_min_tilt, "run ASIFT (slow) only on frames at least this tilted")
      ->capture_default_str();
  c->add_option("--width", a->width, "frame width")->capture_default_str();
  c->add_option("--height", a->height, "frame height")->capture_default_str();
  c->add_option("--jpeg", a->scene.jpeg_quality, "JPEG quality of the frames (0: none)")->capture_default_str();
  c->add_option("--min-gain", a->scene.min_gain, "lowest target contrast gain")->capture_default_str();
  c->add_option("--max-blur", a->scene.max_blur, "max Gaussian blur sigma")->capture_default_str();
  c->add_option("--label", a->label, "name of this run in the report (e.g. the target set)");
  c->add_flag("--diagnose", a->diagnose, "mvkp: also count query points on the target (an extra extraction per frame)");
  c->add_flag("--save-frames", a->save_frames, "also write every frame, its H and a manifest (for eval_pairs.py)");
  AddTrainOptions(c, &a->train);
  AddMatchOptions(c, &a->match, &a->affine);
  c->callback([a, code] { *code = RunSweep(*a); });
}

}  // namespace mvkp::cli
