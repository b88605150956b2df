#include "mvkp/train/trainer.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/synth/synth.h"
#include "mvkp/train/kmeans.h"
#include "mvkp/rifs/rifs.h"

namespace mvkp {
namespace {

struct Detection {
  int view;          // general views first, then rotation views
  bool general;      // from a general view (its descriptor feeds k-means)
  float ox, oy;      // object coordinates (training resolution)
  float radius;      // association radius in object pixels
  int desc;          // row in the descriptor pool
};

}  // namespace

const char* SelectionName(Selection s) { return s == Selection::kRifs ? "rifs" : "stability"; }

void TrainOptions::Check() const {
  auto in = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  Require(in(views, 10, 5000), ErrorCode::kInvalidArgument, "views must be in 10..5000, got " + std::to_string(views));
  Require(in(locations, 1, 100000), ErrorCode::kInvalidArgument, "locations must be in 1..100000, got " + std::to_string(locations));
  Require(in(keep_fraction, 0, 1), ErrorCode::kInvalidArgument, "keep fraction must be in (0, 100%], got " + std::to_string(keep_fraction));
  Require(in(alpha, 0, 1), ErrorCode::kInvalidArgument, "alpha must be in [0, 1], got " + std::to_string(alpha));
  Require(in(rotation_views, 0, 3600), ErrorCode::kInvalidArgument, "rotation views must be in 0..3600, got " + std::to_string(rotation_views));
  Require(in(min_stability, 0, views + rotation_views), ErrorCode::kInvalidArgument,
          "min stability must be in 0.." + std::to_string(views + rotation_views) + " (the number of views), got " +
              std::to_string(min_stability));
  Require(in(clusters, 1, 1000), ErrorCode::kInvalidArgument, "clusters must be in 1..1000, got " + std::to_string(clusters));
  Require(in(kernels, 1, 1023), ErrorCode::kInvalidArgument, "kernels must be in 1..1023, got " + std::to_string(kernels));
  Require(in(points_per_view, 10, 100000), ErrorCode::kInvalidArgument, "points per view must be in 10..100000");
  Require(in(track_radius, 0.5, 20), ErrorCode::kInvalidArgument, "track radius must be in [0.5, 20]");
  Require(in(view_noise, 0, 50), ErrorCode::kInvalidArgument, "view noise must be in [0, 50]");
  Require(in(view_blur, 0, 10), ErrorCode::kInvalidArgument, "view blur must be in [0, 10]");
  Require(max_object_side == 0 || in(max_object_side, 64, 16384), ErrorCode::kInvalidArgument,
          "max object side must be 0 or in 64..16384");
  Require(in(min_locations, 1, 100000), ErrorCode::kInvalidArgument, "min locations must be >= 1");
  Require(in(kmeans_iterations, 0, 1000), ErrorCode::kInvalidArgument, "k-means iterations must be in 0..1000");
  Require(min_scale > 0 && max_scale >= min_scale && max_scale <= 10, ErrorCode::kInvalidArgument,
          "scale range must satisfy 0 < min <= max <= 10");
}

Model Train(const cv::Mat& object_in, const TrainOptions& opt, TrainReport* report) {
  opt.Check();
  CV_Assert(object_in.type() == CV_8UC1);
  Timer total;

  FeatureOptions fo;
  fo.smooth_sigma = opt.smooth_sigma;
  fo.detector.max_points = opt.points_per_view;
  fo.describer.patch_size = opt.patch;
  fo.describer.dims = opt.kernels;
  fo.describer.orient = opt.orient;
  fo.Check();
  const int dims = opt.kernels;

  // Train at a bounded size; locations are mapped back to the input's pixels.
  cv::Mat object = object_in;
  double to_input = 1.0;
  const int side = std::max(object_in.cols, object_in.rows);
  if (opt.max_object_side > 0 && side > opt.max_object_side) {
    to_input = double(side) / opt.max_object_side;
    cv::resize(object_in, object, cv::Size(int(std::lround(object_in.cols / to_input)),
                                           int(std::lround(object_in.rows / to_input))),
               0, 0, cv::INTER_AREA);
  }

  ViewSamplerOptions vso;
  vso.min_scale = opt.min_scale;
  vso.max_scale = opt.max_scale;
  vso.seed = opt.seed;
  auto params = SampleAffineViews(opt.views, vso);
  // Rotation-dominant views (thesis Fig. 3.5): scale 1, one every 360/n degrees.
  // Stability selection ranks by the general views alone (the MVKP baseline).
  const int rotation_views = opt.select == Selection::kRifs ? opt.rotation_views : 0;
  for (int k = 0; k < rotation_views; ++k) {
    AffineParams r;
    r.theta = 2.0 * CV_PI * k / rotation_views;
    params.push_back(r);
  }
  const int total_views = int(params.size());
  cv::RNG rng(opt.seed * 0x9E3779B97F4A7C15ull + 1);

  // Anti-aliasing: the object blurred for a few shrink factors, computed once
  // (a view that shrinks by s uses the level for the next s' <= s).
  struct Level {
    double scale;
    cv::Mat image;
  };
  std::vector<Level> levels = {{1.0, object}};
  for (double s : {0.85, 0.7, 0.55, 0.45, 0.35, 0.25}) {
    if (s < opt.min_scale * 0.5) break;
    const double sigma = 0.6 * std::sqrt(1.0 / (s * s) - 1.0);
    cv::Mat b;
    cv::GaussianBlur(object, b, cv::Size(), sigma, sigma, cv::BORDER_REFLECT_101);
    levels.push_back({s, b});
  }
  // View noise: one Gaussian field, read at a random offset per view.
  cv::Mat noise_field;
  if (opt.view_noise > 0) {
    noise_field.create(512, 512, CV_16SC1);
    rng.fill(noise_field, cv::RNG::NORMAL, 0, opt.view_noise);
  }

  std::vector<Detection> dets;
  std::vector<float> pool;  // descriptors, dims floats each
  const int margin = opt.patch / 2 + 4;
  const double w = object.cols, h = object.rows;
  const float edge_margin = 4.f;  // points this close to the object's outline are dropped
  for (int v = 0; v < total_views; ++v) {
    const cv::Matx22d A = AffineMatrix(params[v]);
    // Place the warped object with a margin of background around it.
    const std::vector<cv::Point2d> c = {{0, 0}, {w - 1, 0}, {w - 1, h - 1}, {0, h - 1}};
    std::vector<cv::Point2d> q(4);
    double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
    for (int k = 0; k < 4; ++k) {
      const cv::Vec2d t = A * cv::Vec2d(c[k].x, c[k].y);
      q[k] = {t[0], t[1]};
      x0 = std::min(x0, t[0]); y0 = std::min(y0, t[1]);
      x1 = std::max(x1, t[0]); y1 = std::max(y1, t[1]);
    }
    const double tx = -x0 + margin + params[v].t1, ty = -y0 + margin + params[v].t2;
    for (auto& p : q) p += cv::Point2d(tx, ty);
    const cv::Matx23d M(A(0, 0), A(0, 1), tx, A(1, 0), A(1, 1), ty);
    const cv::Size size(int(std::ceil(x1 - x0)) + 2 * margin + 4, int(std::ceil(y1 - y0)) + 2 * margin + 4);

    const double shrink = std::sqrt(std::abs(cv::determinant(A)));
    const Level* lv = &levels[0];
    for (const auto& l : levels)
      if (l.scale >= shrink * 0.95) lv = &l;
    cv::Mat view;
    cv::warpAffine(lv->image, view, cv::Mat(M), size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                   cv::Scalar(double(rng.uniform(0, 256))));
    if (opt.view_blur > 0) {
      const double sigma = rng.uniform(0.0, double(opt.view_blur));
      if (sigma > 0.3) cv::GaussianBlur(view, view, cv::Size(), sigma, sigma, cv::BORDER_REFLECT_101);
    }
    if (!noise_field.empty()) {
      const int ox = rng.uniform(0, 512), oy = rng.uniform(0, 512);
      for (int y = 0; y < view.rows; ++y) {
        std::uint8_t* r = view.ptr<std::uint8_t>(y);
        const std::int16_t* n = noise_field.ptr<std::int16_t>((y + oy) & 511);
        for (int x = 0; x < view.cols; ++x) r[x] = cv::saturate_cast<std::uint8_t>(r[x] + n[(x + ox) & 511]);
      }
    }
    Features f = ExtractFeatures(view, fo);

    // Signed distance to each edge of the (convex) warped outline.
    const double orient = (q[1] - q[0]).cross(q[2] - q[1]) > 0 ? 1.0 : -1.0;
    auto inside = [&](double x, double y) {
      for (int k = 0; k < 4; ++k) {
        const cv::Point2d e = q[(k + 1) % 4] - q[k];
        const double d = orient * e.cross(cv::Point2d(x, y) - q[k]) / std::hypot(e.x, e.y);
        if (d < edge_margin) return false;
      }
      return true;
    };
    const cv::Matx22d Ai = A.inv();
    const float radius = float(opt.track_radius / shrink);
    for (int i = 0; i < int(f.keypoints.size()); ++i) {
      const auto& kp = f.keypoints[i];
      if (!inside(kp.x, kp.y)) continue;
      const cv::Vec2d o = Ai * cv::Vec2d(kp.x - tx, kp.y - ty);
      if (o[0] < 0 || o[1] < 0 || o[0] > w - 1 || o[1] > h - 1) continue;
      dets.push_back({v, v < opt.views, float(o[0]), float(o[1]), radius, int(pool.size() / dims)});
      pool.insert(pool.end(), f.descriptors.ptr<float>(i), f.descriptors.ptr<float>(i) + dims);
    }
    if (opt.progress) opt.progress(v + 1, total_views);
  }
  const double views_ms = total.ElapsedMs();

  // Candidate locations: peaks of the detection density in object coordinates.
  cv::Mat density = cv::Mat::zeros(object.size(), CV_32F);
  for (const auto& d : dets) density.at<float>(int(std::lround(d.oy)), int(std::lround(d.ox))) += 1.f;
  cv::GaussianBlur(density, density, cv::Size(), 1.0);
  cv::Mat dil;
  cv::dilate(density, dil, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)));
  struct Cand {
    float x, y, density;
  };
  std::vector<Cand> cands;
  for (int y = 0; y < density.rows; ++y)
    for (int x = 0; x < density.cols; ++x) {
      const float v = density.at<float>(y, x);
      if (v > 0.15f && v >= dil.at<float>(y, x)) cands.push_back({float(x), float(y), v});
    }
  std::stable_sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.density > b.density; });

  // Associate each detection with the nearest candidate within its radius.
  const int cell = 8;
  const int gw = object.cols / cell + 1, gh = object.rows / cell + 1;
  std::vector<std::vector<int>> grid(std::size_t(gw) * gh);
  for (int i = 0; i < int(cands.size()); ++i)
    grid[std::size_t(int(cands[i].y) / cell) * gw + int(cands[i].x) / cell].push_back(i);
  // members[c]: (view, detection) with the closest detection per view.
  std::vector<std::vector<int>> members(cands.size());
  for (int di = 0; di < int(dets.size()); ++di) {
    const auto& d = dets[di];
    const int gx = int(d.ox) / cell, gy = int(d.oy) / cell;
    const int reach = int(std::ceil(d.radius / cell)) + 1;
    int arg = -1;
    float bd = d.radius * d.radius;
    for (int yy = std::max(0, gy - reach); yy <= std::min(gh - 1, gy + reach); ++yy)
      for (int xx = std::max(0, gx - reach); xx <= std::min(gw - 1, gx + reach); ++xx)
        for (int ci : grid[std::size_t(yy) * gw + xx]) {
          const float dx = cands[ci].x - d.ox, dy = cands[ci].y - d.oy;
          const float d2 = dx * dx + dy * dy;
          if (d2 <= bd) { bd = d2; arg = ci; }
        }
    if (arg < 0) continue;
    // One detection per view per location: keep the closest.
    auto& m = members[arg];
    bool replaced = false;
    for (auto& e : m)
      if (dets[e].view == d.view) {
        const float ex = cands[arg].x - dets[e].ox, ey = cands[arg].y - dets[e].oy;
        if (bd < ex * ex + ey * ey) e = di;
        replaced = true;
        break;
      }
    if (!replaced) m.push_back(di);
  }

  // Score the view tracks (SPEC §4) and rank them.
  Timer score_timer;
  RifsOptions ro;
  ro.alpha = opt.select == Selection::kRifs ? opt.alpha : 0.0;
  ro.num_views = total_views;
  ro.min_stability = opt.min_stability > 0 ? opt.min_stability : std::max(3, total_views / 20);
  std::vector<std::vector<int>> track_rows(cands.size());
  std::vector<int> ss(cands.size());
  using SV = TrainOptions::StatsViews;
  const SV stats = rotation_views == 0 ? SV::kAll : opt.stats_views;
  for (std::size_t c = 0; c < cands.size(); ++c) {
    ss[c] = int(members[c].size());
    for (int di : members[c])
      if (stats == SV::kAll || (stats == SV::kGeneral) == dets[di].general) track_rows[c].push_back(dets[di].desc);
  }
  const std::vector<TrackScore> scores = ScoreTracks(pool.data(), dims, track_rows, ro, &ss);
  // Candidates are in decreasing density, so ties fall to the denser peak.
  const std::vector<int> order = RankTracks(scores);
  const double score_ms = score_timer.ElapsedMs();
  auto general_count = [&](int ci) {
    int n = 0;
    for (int di : members[ci]) n += dets[di].general;
    return n;
  };
  int stable = 0;
  for (int ci : order) stable += general_count(ci) > 0;
  if (stable < opt.min_locations)
    throw Error(ErrorCode::kNoTexture, "target has too little texture to train: " + std::to_string(stable) +
                                           " stable interest points, at least " + std::to_string(opt.min_locations) +
                                           " needed");
  const int keep = opt.keep_fraction > 0 ? std::max(1, int(std::lround(opt.keep_fraction * stable))) : opt.locations;

  Timer kmeans_timer;
  Model model;
  model.object_width = object_in.cols;
  model.object_height = object_in.rows;
  std::vector<float> descs;
  std::vector<std::int32_t> labels;
  std::vector<float> samples, centres;
  std::vector<char> kept(cands.size(), 0);
  for (int ci : order) {
    if (int(model.locations.size()) >= keep) break;
    const int ng = general_count(ci);
    if (ng == 0) continue;  // seen in rotation views only: nothing to describe it with
    kept[ci] = 1;
    const int loc = int(model.locations.size());
    // Sub-pixel location: mean of the member detections in object coordinates.
    double sx = 0, sy = 0;
    for (int di : members[ci]) {
      sx += dets[di].ox;
      sy += dets[di].oy;
    }
    sx /= double(members[ci].size());
    sy /= double(members[ci].size());
    model.locations.push_back({float((sx + 0.5) * to_input - 0.5), float((sy + 0.5) * to_input - 0.5),
                               int(members[ci].size())});
    // Rotation views score the tracks; only general views give the descriptors.
    samples.clear();
    for (int di : members[ci]) {
      if (!dets[di].general) continue;
      const float* p = &pool[std::size_t(dets[di].desc) * dims];
      samples.insert(samples.end(), p, p + dims);
    }
    KMeans(samples.data(), ng, dims, opt.clusters, opt.kmeans_iterations,
           opt.seed + 7919ull * std::uint64_t(loc), centres);
    descs.insert(descs.end(), centres.begin(), centres.end());
    for (std::size_t c = 0; c < centres.size() / dims; ++c) labels.push_back(loc);
  }
  const double kmeans_ms = kmeans_timer.ElapsedMs();

  if (report) {
    TrainReport& r = *report;
    r = TrainReport{};
    r.general_views = opt.views;
    r.rotation_views = rotation_views;
    r.min_stability = ro.min_stability;
    r.select = opt.select;
    r.alpha = ro.alpha;
    r.candidates = int(cands.size());
    r.eligible = int(order.size());
    r.kept = int(model.locations.size());
    r.scale_to_input = to_input;
    auto add = [&](int ci, int rank) {
      TrackReport t;
      t.x = float((cands[ci].x + 0.5) * to_input - 0.5);
      t.y = float((cands[ci].y + 0.5) * to_input - 0.5);
      t.score = scores[ci];
      t.general = general_count(ci);
      t.rank = rank;
      t.kept = kept[ci];
      r.tracks.push_back(t);
    };
    for (int i = 0; i < int(order.size()); ++i) add(order[i], i);
    for (int ci = 0; ci < int(cands.size()); ++ci)
      if (!scores[ci].eligible) add(ci, -1);
    r.views_ms = views_ms;
    r.score_ms = score_ms;
    r.kmeans_ms = kmeans_ms;
  }
  model.descriptors = cv::Mat(int(labels.size()), dims, CV_32F, descs.data()).clone();
  model.labels = labels;

  ModelParams& p = model.params;
  p.smooth_sigma = fo.smooth_sigma;
  p.patch_size = fo.describer.patch_size;
  p.dims = dims;
  p.orient = fo.describer.orient;
  p.orientation_radius = fo.describer.orientation_radius;
  p.min_strength = fo.detector.min_strength;
  p.relative_threshold = fo.detector.relative_threshold;
  p.min_distance = fo.detector.min_distance;
  p.block_size = fo.detector.block_size;
  p.views = opt.views;
  p.locations = opt.locations;
  p.clusters = opt.clusters;
  p.seed = opt.seed;
  p.min_scale = float(opt.min_scale);
  p.max_scale = float(opt.max_scale);
  p.train_ms = total.ElapsedMs();
  if (report) report->total_ms = p.train_ms;
  return model;
}

}  // namespace mvkp
