#include "mvkp/train/trainer.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/rifs/rifs.h"
#include "mvkp/synth/camera_view.h"
#include "mvkp/synth/synth.h"
#include "mvkp/index/kmeans.h"

namespace mvkp {
namespace {

struct Detection {
  int view;          // general views first, then rotation views
  bool general;      // from a general view (its descriptor feeds k-means)
  float ox, oy;      // level coordinates
  float radius;      // association radius in level pixels
  int desc;          // row in the descriptor pool
};

// One synthetic view: H maps level pixels to view pixels.
struct ViewSpec {
  cv::Matx33d H;
  cv::Size size;
  bool general = true;
};

constexpr double kDeg = CV_PI / 180.0;

// Places the warped outline with `margin` pixels of background around it.
ViewSpec Frame(const cv::Matx33d& H0, cv::Size level, int margin, int t1, int t2) {
  const auto q = OutlineUnder(H0, level);
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto& p : q) {
    x0 = std::min(x0, p.x); y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x); y1 = std::max(y1, p.y);
  }
  const cv::Matx33d T(1, 0, -x0 + margin + t1, 0, 1, -y0 + margin + t2, 0, 0, 1);
  ViewSpec v;
  v.H = T * H0;
  v.H *= 1.0 / v.H(2, 2);
  v.size = cv::Size(int(std::ceil(x1 - x0)) + 2 * margin + 4, int(std::ceil(y1 - y0)) + 2 * margin + 4);
  return v;
}

// The thesis's affine views (SPEC §2.2) over lambda in [min_scale, max_scale].
std::vector<ViewSpec> AffineViews(cv::Size level, int n, const TrainOptions& o, int margin) {
  ViewSamplerOptions vso;
  vso.min_scale = o.min_scale;
  vso.max_scale = o.max_scale;
  vso.seed = o.seed;
  std::vector<ViewSpec> out;
  for (const AffineParams& p : SampleAffineViews(n, vso)) {
    const cv::Matx22d A = AffineMatrix(p);
    out.push_back(Frame(cv::Matx33d(A(0, 0), A(0, 1), 0, A(1, 0), A(1, 1), 0, 0, 0, 1), level, margin, p.t1, p.t2));
  }
  return out;
}

// Camera-model views of one level: tilt (ASIFT-style), azimuth, roll, scale,
// field of view and where in a 640x480 frame the target sits (off-centre
// targets get the perspective of a wide lens), from a shifted Halton sequence.
std::vector<ViewSpec> CameraViews(cv::Size level, int n, const TrainOptions& o, int level_index, int margin,
                                  double min_tilt, double frontal_share, double min_scale, double max_scale) {
  std::mt19937_64 rng(o.seed * 0x9E3779B97F4A7C15ull + 1000003ull * std::uint64_t(level_index + 1));
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  constexpr int kDims = 7;
  const int bases[kDims] = {2, 3, 5, 7, 11, 13, 17};
  double shift[kDims];
  for (double& s : shift) s = u01(rng);
  std::uniform_int_distribution<int> ut(0, 3);
  // ASIFT-style: uniform in the tilt factor t = 1/cos(tilt) above `frontal`
  // (the appearance changes as fast with t as the views get steeper), a
  // share uniform in angle below it.
  const double frontal = std::min(min_tilt > 0 ? min_tilt : 40.0, o.max_tilt_deg);
  const double t_f = 1.0 / std::cos(frontal * kDeg), t_max = 1.0 / std::cos(o.max_tilt_deg * kDeg);
  const cv::Size frame(640, 480);
  std::vector<ViewSpec> out;
  for (int i = 0; i < n; ++i) {
    double h[kDims];
    for (int d = 0; d < kDims; ++d) h[d] = std::fmod(RadicalInverse(bases[d], std::uint64_t(i) + 1) + shift[d], 1.0);
    CameraPose p;
    if (o.max_tilt_deg <= frontal || frontal_share >= 1) {
      p.tilt_deg = frontal * h[0];
    } else if (h[0] < frontal_share) {
      p.tilt_deg = frontal * h[0] / frontal_share;
    } else {
      const double t = t_f + (h[0] - frontal_share) / (1 - frontal_share) * (t_max - t_f);
      p.tilt_deg = std::acos(1.0 / t) / kDeg;
    }
    p.azimuth_deg = 180.0 * h[1];  // tilting about an axis and its opposite look alike
    p.roll_deg = 360.0 * h[2] - 180.0;
    const double side = std::max(level.width, level.height);
    p.size_px = side * std::exp(std::log(min_scale) + h[3] * (std::log(max_scale) - std::log(min_scale)));
    p.hfov_deg = 45.0 + 25.0 * h[4];
    // The target's centre somewhere in the frame's middle 60 %.
    p.centre = {frame.width * (0.2 + 0.6 * h[5]), frame.height * (0.2 + 0.6 * h[6])};
    const cv::Matx33d H0 = CameraHomography(level, frame, p);
    out.push_back(Frame(H0, level, margin, ut(rng), ut(rng)));
  }
  return out;
}

// The level image pre-blurred for a few shrink factors (a view that shrinks by
// s uses the blur of the next factor s' >= s).
struct BlurLadder {
  struct Rung {
    double scale;
    cv::Mat image;
  };
  std::vector<Rung> rungs;
  BlurLadder(const cv::Mat& img, double min_scale) {
    rungs.push_back({1.0, img});
    for (double s : {0.85, 0.7, 0.55, 0.45, 0.35, 0.25}) {
      if (s < min_scale * 0.5) break;
      const double sigma = 0.6 * std::sqrt(1.0 / (s * s) - 1.0);
      cv::Mat b;
      cv::GaussianBlur(img, b, cv::Size(), sigma, sigma, cv::BORDER_REFLECT_101);
      rungs.push_back({s, b});
    }
  }
  const cv::Mat& For(double shrink) const {
    const Rung* r = &rungs[0];
    for (const auto& x : rungs)
      if (x.scale >= shrink * 0.95) r = &x;
    return r->image;
  }
};

// Renders a view: isotropic anti-aliasing for the view's larger scale, then,
// where the view compresses one direction much more (a steep tilt), a 1-D
// Gaussian along that direction (the image is rotated so it is vertical, as
// ASIFT does), and the perspective warp onto a flat random background.
cv::Mat RenderView(const BlurLadder& ladder, const ViewSpec& v, double smin, double smax, const cv::Vec2d& dir_min,
                   int background) {
  const cv::Mat& src = ladder.For(smax);
  cv::Mat view;
  if (smin < 0.75 * smax && smin < 0.95) {
    const double sigma = 0.6 * std::sqrt(std::max(0.0, 1.0 / (smin * smin) - 1.0 / std::min(1.0, smax * smax)));
    // Rotate so dir_min becomes the y axis, about the image centre, into a canvas holding all of it.
    const double ang = std::atan2(dir_min[1], dir_min[0]) - CV_PI / 2;  // rotate by -ang
    const double c = std::cos(-ang), s = std::sin(-ang);
    const double cx = 0.5 * (src.cols - 1), cy = 0.5 * (src.rows - 1);
    const double hw = 0.5 * (std::abs(c) * src.cols + std::abs(s) * src.rows) + 2;
    const double hh = 0.5 * (std::abs(s) * src.cols + std::abs(c) * src.rows) + 2;
    const cv::Matx33d R(c, -s, hw - (c * cx - s * cy), s, c, hh - (s * cx + c * cy), 0, 0, 1);
    cv::Mat rot;
    cv::warpAffine(src, rot, cv::Mat(cv::Matx23d(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2))),
                   cv::Size(int(2 * hw), int(2 * hh)), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(background));
    const int k = 2 * int(std::ceil(3 * sigma)) + 1;
    const cv::Mat gy = cv::getGaussianKernel(k, sigma, CV_32F), one = cv::Mat::ones(1, 1, CV_32F);
    cv::sepFilter2D(rot, rot, -1, one, gy, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
    cv::warpPerspective(rot, view, cv::Mat(v.H * R.inv()), v.size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                        cv::Scalar(background));
  } else {
    cv::warpPerspective(src, view, cv::Mat(v.H), v.size, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(background));
  }
  return view;
}

struct LevelOut {
  std::vector<ObjectLocation> locations;  // in input pixels
  std::vector<float> centres;
  std::vector<std::int32_t> labels;       // local to this level
  int stable = 0;
  std::vector<TrackReport> tracks;
  int candidates = 0, eligible = 0, min_stability = 0;
  double views_ms = 0, score_ms = 0, kmeans_ms = 0;
};

// Views, tracks, ranking and k-means of one pyramid level. `to_input`: input
// pixels per level pixel.
LevelOut TrainLevel(const cv::Mat& object, double to_input, int level_index, int keep_count, const TrainOptions& opt,
                    const FeatureOptions& fo, int progress_done, int progress_total) {
  LevelOut out;
  Timer timer;
  const int dims = fo.describer.dims;
  const int margin = opt.patch / 2 + 4;
  std::vector<ViewSpec> views;
  if (opt.view_model == ViewModel::kCamera) {
    views = CameraViews(object.size(), opt.views, opt, level_index, margin, 0, opt.frontal_share, opt.level_min_scale,
                        opt.level_max_scale);
  } else {
    views = AffineViews(object.size(), opt.views, opt, margin);
    if (opt.view_model == ViewModel::kMixed && opt.camera_views > 0) {
      const auto steep = CameraViews(object.size(), opt.camera_views, opt, level_index, margin, opt.camera_min_tilt, 0,
                                     opt.min_scale, opt.max_scale);
      views.insert(views.end(), steep.begin(), steep.end());
    }
  }
  // Rotation-dominant views (thesis Fig. 3.5): scale 1, one every 360/n degrees.
  const int rotation_views = opt.select == Selection::kRifs ? opt.rotation_views : 0;
  for (int k = 0; k < rotation_views; ++k) {
    AffineParams r;
    r.theta = 2.0 * CV_PI * k / rotation_views;
    const cv::Matx22d A = AffineMatrix(r);
    ViewSpec v = Frame(cv::Matx33d(A(0, 0), A(0, 1), 0, A(1, 0), A(1, 1), 0, 0, 0, 1), object.size(), margin, 0, 0);
    v.general = false;
    views.push_back(v);
  }
  const int total_views = int(views.size());
  cv::RNG rng(opt.seed * 0x9E3779B97F4A7C15ull + 1 + 7777ull * std::uint64_t(level_index));

  double min_shrink = 1.0;
  std::vector<cv::Vec2d> sv(views.size());
  std::vector<cv::Vec2d> dir(views.size());
  const cv::Point2d centre(0.5 * (object.cols - 1), 0.5 * (object.rows - 1));
  for (std::size_t v = 0; v < views.size(); ++v) {
    sv[v] = LocalScales(views[v].H, centre);
    min_shrink = std::min(min_shrink, sv[v][1]);
    // Direction (object plane) of the smallest stretch: the right singular vector.
    const cv::Matx33d& H = views[v].H;
    const double w = H(2, 0) * centre.x + H(2, 1) * centre.y + H(2, 2);
    const double x = (H(0, 0) * centre.x + H(0, 1) * centre.y + H(0, 2)) / w;
    const double y = (H(1, 0) * centre.x + H(1, 1) * centre.y + H(1, 2)) / w;
    const cv::Matx22d J((H(0, 0) - x * H(2, 0)) / w, (H(0, 1) - x * H(2, 1)) / w, (H(1, 0) - y * H(2, 0)) / w,
                        (H(1, 1) - y * H(2, 1)) / w);
    cv::Mat S, U, Vt;
    cv::SVD::compute(cv::Mat(J), S, U, Vt);
    dir[v] = {Vt.at<double>(1, 0), Vt.at<double>(1, 1)};
  }
  const BlurLadder ladder(object, std::min(opt.min_scale, min_shrink));
  cv::Mat noise_field;
  if (opt.view_noise > 0) {
    noise_field.create(512, 512, CV_16SC1);
    rng.fill(noise_field, cv::RNG::NORMAL, 0, opt.view_noise);
  }

  std::vector<Detection> dets;
  std::vector<float> pool;  // descriptors, dims floats each
  const double w = object.cols, h = object.rows;
  const float edge_margin = 4.f;  // points this close to the object's outline are dropped
  for (int v = 0; v < total_views; ++v) {
    const ViewSpec& vs = views[v];
    cv::Mat view = RenderView(ladder, vs, sv[v][0], sv[v][1], dir[v], rng.uniform(0, 256));
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
    const auto qa = OutlineUnder(vs.H, object.size());
    const std::vector<cv::Point2d> q(qa.begin(), qa.end());
    const double orient = (q[1] - q[0]).cross(q[2] - q[1]) > 0 ? 1.0 : -1.0;
    auto inside = [&](double x, double y) {
      for (int k = 0; k < 4; ++k) {
        const cv::Point2d e = q[(k + 1) % 4] - q[k];
        const double d = orient * e.cross(cv::Point2d(x, y) - q[k]) / std::hypot(e.x, e.y);
        if (d < edge_margin) return false;
      }
      return true;
    };
    const cv::Matx33d Hi = vs.H.inv();
    const double geo = std::sqrt(sv[v][0] * sv[v][1]);
    const float radius = float(std::min(3.0 * opt.track_radius, opt.track_radius / geo));
    for (int i = 0; i < int(f.keypoints.size()); ++i) {
      const auto& kp = f.keypoints[i];
      if (!inside(kp.x, kp.y)) continue;
      const cv::Vec3d o = Hi * cv::Vec3d(kp.x, kp.y, 1.0);
      const double ox = o[0] / o[2], oy = o[1] / o[2];
      if (!(ox >= 0 && oy >= 0 && ox <= w - 1 && oy <= h - 1)) continue;
      dets.push_back({v, vs.general, float(ox), float(oy), radius, int(pool.size() / dims)});
      pool.insert(pool.end(), f.descriptors.ptr<float>(i), f.descriptors.ptr<float>(i) + dims);
    }
    if (opt.progress) opt.progress(progress_done + v + 1, std::max(progress_total, progress_done + total_views));
  }
  out.views_ms = timer.ElapsedMs();

  // Candidate locations: peaks of the detection density in level coordinates.
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
      const float val = density.at<float>(y, x);
      if (val > 0.15f && val >= dil.at<float>(y, x)) cands.push_back({float(x), float(y), val});
    }
  std::stable_sort(cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.density > b.density; });

  // Associate each detection with the nearest candidate within its radius.
  const int cell = 8;
  const int gw = object.cols / cell + 1, gh = object.rows / cell + 1;
  std::vector<std::vector<int>> grid(std::size_t(gw) * gh);
  for (int i = 0; i < int(cands.size()); ++i)
    grid[std::size_t(int(cands[i].y) / cell) * gw + int(cands[i].x) / cell].push_back(i);
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
  ro.min_stability = opt.min_stability > 0 ? std::min(opt.min_stability, total_views) : std::max(3, total_views / 20);
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
  const std::vector<int> order = RankTracks(scores);
  out.score_ms = score_timer.ElapsedMs();
  auto general_count = [&](int ci) {
    int n = 0;
    for (int di : members[ci]) n += dets[di].general;
    return n;
  };
  for (int ci : order) out.stable += general_count(ci) > 0;
  const int keep = opt.keep_fraction > 0 ? std::max(1, int(std::lround(opt.keep_fraction * out.stable))) : keep_count;

  Timer kmeans_timer;
  std::vector<float> samples, centres;
  std::vector<char> kept(cands.size(), 0);
  for (int ci : order) {
    if (int(out.locations.size()) >= keep) break;
    const int ng = general_count(ci);
    if (ng == 0) continue;  // seen in rotation views only: nothing to describe it with
    kept[ci] = 1;
    const int loc = int(out.locations.size());
    double sx = 0, sy = 0;
    for (int di : members[ci]) {
      sx += dets[di].ox;
      sy += dets[di].oy;
    }
    sx /= double(members[ci].size());
    sy /= double(members[ci].size());
    ObjectLocation ol;
    ol.x = float((sx + 0.5) * to_input - 0.5);
    ol.y = float((sy + 0.5) * to_input - 0.5);
    ol.stability = int(members[ci].size());
    ol.level = level_index;
    ol.scale = float(to_input);
    out.locations.push_back(ol);
    samples.clear();
    for (int di : members[ci]) {
      if (!dets[di].general) continue;
      const float* p = &pool[std::size_t(dets[di].desc) * dims];
      samples.insert(samples.end(), p, p + dims);
    }
    KMeans(samples.data(), ng, dims, opt.clusters, opt.kmeans_iterations,
           opt.seed + 7919ull * std::uint64_t(loc) + 104729ull * std::uint64_t(level_index), centres);
    out.centres.insert(out.centres.end(), centres.begin(), centres.end());
    for (std::size_t c = 0; c < centres.size() / dims; ++c) out.labels.push_back(loc);
  }
  out.kmeans_ms = kmeans_timer.ElapsedMs();

  out.candidates = int(cands.size());
  out.eligible = int(order.size());
  out.min_stability = ro.min_stability;
  auto add = [&](int ci, int rank) {
    TrackReport t;
    t.x = float((cands[ci].x + 0.5) * to_input - 0.5);
    t.y = float((cands[ci].y + 0.5) * to_input - 0.5);
    t.level = level_index;
    t.score = scores[ci];
    t.general = general_count(ci);
    t.rank = rank;
    t.kept = kept[ci];
    out.tracks.push_back(t);
  };
  for (int i = 0; i < int(order.size()); ++i) add(order[i], i);
  for (int ci = 0; ci < int(cands.size()); ++ci)
    if (!scores[ci].eligible) add(ci, -1);
  return out;
}

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
  Require(in(levels, 0, 8), ErrorCode::kInvalidArgument, "levels must be in 0..8 (0: auto), got " + std::to_string(levels));
  Require(in(min_apparent_size, 8, 100000), ErrorCode::kInvalidArgument, "min apparent size must be >= 8 pixels");
  Require(in(min_level_size, 16, 100000), ErrorCode::kInvalidArgument, "min level size must be >= 16 pixels");
  Require(level_min_scale > 0.05 && level_max_scale >= level_min_scale && level_max_scale <= 4, ErrorCode::kInvalidArgument,
          "level scale range must satisfy 0.05 < min <= max <= 4");
  Require(in(max_tilt_deg, 0, 85), ErrorCode::kInvalidArgument, "max tilt must be in [0, 85] degrees");
  Require(in(frontal_share, 0, 1), ErrorCode::kInvalidArgument, "frontal share must be in [0, 1]");
  Require(in(camera_views, 0, 5000), ErrorCode::kInvalidArgument, "camera views must be in 0..5000");
  Require(in(camera_min_tilt, 0, 85), ErrorCode::kInvalidArgument, "camera min tilt must be in [0, 85] degrees");
  Require(level_locations > 0 && level_locations <= 4, ErrorCode::kInvalidArgument, "level locations must be in (0, 4]");
}

std::vector<int> TrainingLevelSizes(int top_side, const TrainOptions& o) {
  std::vector<int> sizes = {top_side};
  const int want = o.levels > 0 ? o.levels : 8;
  while (int(sizes.size()) < want) {
    const double s = sizes.back();
    if (o.levels == 0 && s * (o.view_model == ViewModel::kCamera ? o.level_min_scale : o.min_scale) <= o.min_apparent_size)
      break;
    const int next = int(std::lround(s / 2));
    if (next < o.min_level_size) break;
    sizes.push_back(next);
  }
  if (o.view_model == ViewModel::kAffine && o.levels == 0) sizes.resize(1);  // the thesis: one resolution
  return sizes;
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
  const int side = std::max(object_in.cols, object_in.rows);
  const int top = opt.max_object_side > 0 ? std::min(side, opt.max_object_side) : side;
  const std::vector<int> sizes = TrainingLevelSizes(top, opt);

  Model model;
  model.object_width = object_in.cols;
  model.object_height = object_in.rows;
  std::vector<float> descs;
  std::vector<std::int32_t> labels;
  if (report) *report = TrainReport{};
  double keep = opt.locations;
  // Progress over all levels: every level has the same number of views.
  const int per_level = opt.views + (opt.view_model == ViewModel::kMixed ? opt.camera_views : 0) +
                        (opt.select == Selection::kRifs ? opt.rotation_views : 0);
  const int progress_total = per_level * int(sizes.size());
  for (int li = 0; li < int(sizes.size()); ++li) {
    cv::Mat object = object_in;
    double to_input = 1.0;
    if (sizes[li] != side) {
      to_input = double(side) / sizes[li];
      cv::resize(object_in, object, cv::Size(std::max(1, int(std::lround(object_in.cols / to_input))),
                                             std::max(1, int(std::lround(object_in.rows / to_input)))),
                 0, 0, cv::INTER_AREA);
      // Exact per-axis factors after rounding.
      to_input = double(object_in.cols) / object.cols;
    }
    const int keep_here = std::max(1, int(std::lround(keep)));
    LevelOut lv = TrainLevel(object, to_input, li, keep_here, opt, fo, li * per_level, progress_total);
    keep *= opt.level_locations;
    if (li == 0 && lv.stable < opt.min_locations)
      throw Error(ErrorCode::kNoTexture, "target has too little texture to train: " + std::to_string(lv.stable) +
                                             " stable interest points when trained at " + std::to_string(sizes[li]) +
                                             " px, at least " + std::to_string(opt.min_locations) + " needed");
    if (li > 0 && int(lv.locations.size()) < 4) {  // too small to add anything useful
      if (opt.progress) opt.progress(progress_total, progress_total);
      break;
    }
    const int base = int(model.locations.size());
    model.locations.insert(model.locations.end(), lv.locations.begin(), lv.locations.end());
    descs.insert(descs.end(), lv.centres.begin(), lv.centres.end());
    for (auto l : lv.labels) labels.push_back(l + base);
    if (report) {
      TrainReport& r = *report;
      if (li == 0) {
        r.general_views = opt.views + (opt.view_model == ViewModel::kMixed ? opt.camera_views : 0);
        r.rotation_views = opt.select == Selection::kRifs ? opt.rotation_views : 0;
        r.min_stability = lv.min_stability;
        r.select = opt.select;
        r.alpha = opt.select == Selection::kRifs ? opt.alpha : 0.0;
        r.scale_to_input = to_input;
      }
      r.candidates += lv.candidates;
      r.eligible += lv.eligible;
      r.kept += int(lv.locations.size());
      r.level_sizes.push_back(sizes[li]);
      r.level_kept.push_back(int(lv.locations.size()));
      // Ranks are per level; later levels continue the numbering.
      const int rank_base = li == 0 ? 0 : int(std::count_if(r.tracks.begin(), r.tracks.end(), [](const TrackReport& t) { return t.rank >= 0; }));
      std::vector<TrackReport> ranked, rest;
      for (auto t : lv.tracks) {
        if (t.rank >= 0) {
          t.rank += rank_base;
          ranked.push_back(t);
        } else {
          rest.push_back(t);
        }
      }
      // Keep "ranked first, then ineligible" over all levels.
      std::vector<TrackReport> merged;
      for (const auto& t : r.tracks) if (t.rank >= 0) merged.push_back(t);
      merged.insert(merged.end(), ranked.begin(), ranked.end());
      for (const auto& t : r.tracks) if (t.rank < 0) merged.push_back(t);
      merged.insert(merged.end(), rest.begin(), rest.end());
      r.tracks = std::move(merged);
      r.views_ms += lv.views_ms;
      r.score_ms += lv.score_ms;
      r.kmeans_ms += lv.kmeans_ms;
    }
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
  p.view_model = std::uint8_t(opt.view_model == ViewModel::kAffine ? 0 : opt.view_model == ViewModel::kCamera ? 1 : 2);
  p.levels = 1;
  for (const auto& l : model.locations) p.levels = std::max(p.levels, l.level + 1);
  p.max_tilt_deg = opt.view_model == ViewModel::kAffine ? 0.f : float(opt.max_tilt_deg);
  p.level_min_scale = float(opt.level_min_scale);
  p.level_max_scale = float(opt.level_max_scale);
  p.train_ms = total.ElapsedMs();
  if (report) report->total_ms = p.train_ms;
  return model;
}

}  // namespace mvkp
