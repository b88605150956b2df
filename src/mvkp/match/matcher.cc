#include "mvkp/match/matcher.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/ivf.h"
#include "mvkp/index/kmeans.h"
#include "mvkp/synth/camera_view.h"

namespace mvkp {

void MatchOptions::Check() const {
  Require(max_points >= 4 && max_points <= 100000, ErrorCode::kInvalidArgument, "max points must be in 4..100000");
  Require(working_size == 0 || (working_size >= 64 && working_size <= 65536), ErrorCode::kInvalidArgument,
          "working size must be 0 or in 64..65536");
  Require(upsample_points >= 0 && upsample_points <= 100000, ErrorCode::kInvalidArgument,
          "upsample points must be in 0..100000");
  Require(tilt_directions >= 0 && tilt_directions <= 64, ErrorCode::kInvalidArgument, "tilt directions must be in 0..64");
  Require(tilt_points >= 4 && tilt_points <= 100000, ErrorCode::kInvalidArgument, "tilt points must be in 4..100000");
  for (float t : tilt_factors)
    Require(t >= 1.1f && t <= 8.f, ErrorCode::kInvalidArgument, "tilt factors must be in [1.1, 8]");
  Require(grid_cells >= 1 && grid_cells <= 256, ErrorCode::kInvalidArgument, "grid cells must be in 1..256");
  Require(grid_share >= 0.f && grid_share <= 1.f, ErrorCode::kInvalidArgument, "grid share must be in [0, 1]");
  Require(half_res_points >= 0 && half_res_points <= 100000, ErrorCode::kInvalidArgument,
          "half-resolution points must be in 0..100000");
  Require(first_pass_points >= 0 && first_pass_points <= 100000, ErrorCode::kInvalidArgument,
          "first-pass points must be in 0..100000");
  Require(steep_anisotropy >= 0 && steep_anisotropy <= 1, ErrorCode::kInvalidArgument,
          "steep anisotropy must be in [0, 1]");
  Require(retry_below_inliers >= 0, ErrorCode::kInvalidArgument, "retry threshold must be >= 0");
  Require(ratio > 0.f && ratio <= 1.f, ErrorCode::kInvalidArgument, "ratio must be in (0, 1]");
  Require(dynamic_goal >= 0, ErrorCode::kInvalidArgument, "dynamic goal must be >= 0");
  Require(dynamic_checks >= 1 && dynamic_checks <= 1000, ErrorCode::kInvalidArgument, "dynamic checks must be in 1..1000");
  Require(ratio_min > 0.f && ratio_min <= ratio_max && ratio_max <= 1.f, ErrorCode::kInvalidArgument,
          "dynamic ratio bounds must satisfy 0 < min <= max <= 1");
  Require(ransac_threshold > 0 && ransac_threshold <= 100, ErrorCode::kInvalidArgument, "RANSAC threshold must be in (0, 100]");
  Require(ransac_iterations >= 1 && ransac_iterations <= 1000000, ErrorCode::kInvalidArgument, "RANSAC iterations must be in 1..1e6");
  Require(ransac_confidence > 0 && ransac_confidence < 1, ErrorCode::kInvalidArgument, "RANSAC confidence must be in (0, 1)");
  Require(index == "exact" || index == "approx" || index == "brute" || index == "ivf", ErrorCode::kInvalidArgument,
          "index must be ivf, exact, approx or brute");
  Require(nprobe >= 1 && nprobe <= 4096, ErrorCode::kInvalidArgument, "nprobe must be in 1..4096");
  Require(min_inliers >= 4, ErrorCode::kInvalidArgument, "min inliers must be >= 4");
}

double MeanCornerError(const cv::Matx33d& a, const cv::Matx33d& b, cv::Size s) {
  const std::vector<cv::Point2d> c = {{0, 0}, {s.width - 1.0, 0}, {s.width - 1.0, s.height - 1.0}, {0, s.height - 1.0}};
  std::vector<cv::Point2d> pa, pb;
  cv::perspectiveTransform(c, pa, cv::Mat(a));
  cv::perspectiveTransform(c, pb, cv::Mat(b));
  double e = 0;
  for (int i = 0; i < 4; ++i) e += cv::norm(pa[i] - pb[i]);
  return std::isfinite(e) ? e / 4 : std::numeric_limits<double>::infinity();
}

bool IsPlausibleOutline(const std::array<cv::Point2f, 4>& q, double min_area) {
  for (const auto& p : q)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || std::abs(p.x) > 1e6 || std::abs(p.y) > 1e6) return false;
  int sign = 0;
  for (int i = 0; i < 4; ++i) {
    const cv::Point2f a = q[(i + 1) % 4] - q[i], b = q[(i + 2) % 4] - q[(i + 1) % 4];
    const double cross = double(a.x) * b.y - double(a.y) * b.x;
    const int s = cross > 0 ? 1 : (cross < 0 ? -1 : 0);
    if (s == 0 || (sign != 0 && s != sign)) return false;
    sign = s;
  }
  std::vector<cv::Point2f> poly(q.begin(), q.end());
  return std::abs(cv::contourArea(poly)) >= min_area;
}

bool FitHomographyLeastSquares(const std::vector<cv::Point2f>& src, const std::vector<cv::Point2f>& dst,
                               const cv::Matx33d& start, cv::Matx33d& H) {
  const std::size_t n = std::min(src.size(), dst.size());
  if (n < 4) return false;
  // Similarity normalisation: centroid at 0, mean distance sqrt(2). A
  // similarity of dst scales every residual alike, so the minimiser is the
  // same as in pixels.
  auto normaliser = [n](const std::vector<cv::Point2f>& p) {
    double cx = 0, cy = 0;
    for (std::size_t i = 0; i < n; ++i) {
      cx += p[i].x;
      cy += p[i].y;
    }
    cx /= double(n);
    cy /= double(n);
    double r = 0;
    for (std::size_t i = 0; i < n; ++i) r += std::hypot(p[i].x - cx, p[i].y - cy);
    r /= double(n);
    const double s = r > 1e-12 ? std::sqrt(2.0) / r : 1.0;
    return cv::Matx33d(s, 0, -s * cx, 0, s, -s * cy, 0, 0, 1);
  };
  const cv::Matx33d Ts = normaliser(src), Td = normaliser(dst);
  std::vector<cv::Vec2d> a(n), b(n);
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = {Ts(0, 0) * src[i].x + Ts(0, 2), Ts(1, 1) * src[i].y + Ts(1, 2)};
    b[i] = {Td(0, 0) * dst[i].x + Td(0, 2), Td(1, 1) * dst[i].y + Td(1, 2)};
  }
  cv::Matx33d G = Td * start * Ts.inv();
  if (!(std::abs(G(2, 2)) > 1e-12)) return false;
  G *= 1.0 / G(2, 2);
  cv::Vec<double, 8> p(G(0, 0), G(0, 1), G(0, 2), G(1, 0), G(1, 1), G(1, 2), G(2, 0), G(2, 1));
  auto cost = [&](const cv::Vec<double, 8>& h) {
    double c = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double x = a[i][0], y = a[i][1], w = h[6] * x + h[7] * y + 1;
      const double ex = (h[0] * x + h[1] * y + h[2]) / w - b[i][0], ey = (h[3] * x + h[4] * y + h[5]) / w - b[i][1];
      c += ex * ex + ey * ey;
    }
    return c;
  };
  double c0 = cost(p);
  if (!std::isfinite(c0)) return false;
  double lambda = 1e-6;
  for (int it = 0; it < 30; ++it) {
    cv::Matx<double, 8, 8> A = cv::Matx<double, 8, 8>::zeros();
    cv::Vec<double, 8> g = cv::Vec<double, 8>::all(0);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = a[i][0], y = a[i][1], iw = 1.0 / (p[6] * x + p[7] * y + 1);
      const double X = (p[0] * x + p[1] * y + p[2]) * iw, Y = (p[3] * x + p[4] * y + p[5]) * iw;
      const double jx[8] = {x * iw, y * iw, iw, 0, 0, 0, -X * x * iw, -X * y * iw};
      const double jy[8] = {0, 0, 0, x * iw, y * iw, iw, -Y * x * iw, -Y * y * iw};
      const double rx = X - b[i][0], ry = Y - b[i][1];
      for (int r = 0; r < 8; ++r) {
        g[r] += jx[r] * rx + jy[r] * ry;
        for (int c = r; c < 8; ++c) A(r, c) += jx[r] * jx[c] + jy[r] * jy[c];
      }
    }
    for (int r = 0; r < 8; ++r)
      for (int c = 0; c < r; ++c) A(r, c) = A(c, r);
    bool improved = false;
    while (lambda < 1e10) {
      cv::Matx<double, 8, 8> D = A;
      for (int r = 0; r < 8; ++r) D(r, r) += lambda * std::max(A(r, r), 1e-12);
      // Zero when the factorisation fails (degenerate points): no change.
      const cv::Vec<double, 8> step = D.solve(-g, cv::DECOMP_CHOLESKY);
      const cv::Vec<double, 8> q = p + step;
      const double c1 = cost(q);
      if (std::isfinite(c1) && c1 <= c0) {
        const bool done = c0 - c1 <= 1e-14 * c0 + 1e-30 || cv::norm(step) <= 1e-12 * (cv::norm(p) + 1e-12);
        p = q;
        c0 = c1;
        lambda = std::max(lambda * 0.1, 1e-12);
        improved = !done;
        break;
      }
      lambda *= 10;
    }
    if (!improved) break;
  }
  const cv::Matx33d Gn(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], 1);
  cv::Matx33d Hn = Td.inv() * Gn * Ts;
  if (!(std::abs(Hn(2, 2)) > 1e-15)) return false;
  Hn *= 1.0 / Hn(2, 2);
  for (int i = 0; i < 9; ++i)
    if (!std::isfinite(Hn.val[i])) return false;
  H = Hn;
  return true;
}

std::vector<std::int32_t> LocationPlaces(const Model& model) {
  const int n = int(model.locations.size());
  std::vector<std::int32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  if (model.params.levels > 1) {
    // Grid over the object with cells as large as the widest join radius.
    float reach = 0;
    for (const auto& l : model.locations) reach = std::max(reach, 2.f * l.scale);
    const float cell = std::max(1.f, reach);
    const int gw = int(model.object_width / cell) + 2, gh = int(model.object_height / cell) + 2;
    std::vector<std::vector<int>> grid(std::size_t(gw) * gh);
    auto cell_of = [&](float v, int lim) { return std::clamp(int(v / cell), 0, lim - 1); };
    for (int i = 0; i < n; ++i)
      grid[std::size_t(cell_of(model.locations[i].y, gh)) * gw + cell_of(model.locations[i].x, gw)].push_back(i);
    for (int i = 0; i < n; ++i) {
      const auto& a = model.locations[i];
      const int cx = cell_of(a.x, gw), cy = cell_of(a.y, gh);
      for (int yy = std::max(0, cy - 1); yy <= std::min(gh - 1, cy + 1); ++yy)
        for (int xx = std::max(0, cx - 1); xx <= std::min(gw - 1, cx + 1); ++xx)
          for (int j : grid[std::size_t(yy) * gw + xx]) {
            if (j <= i) continue;
            const auto& b = model.locations[j];
            if (a.level == b.level) continue;
            const float r = 2.f * std::max(a.scale, b.scale);
            if ((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) <= r * r) parent[find(i)] = find(j);
          }
    }
  }
  std::vector<std::int32_t> place(n);
  for (int i = 0; i < n; ++i) place[i] = find(i);
  return place;
}

Matcher::Matcher(const Model& model, const MatchOptions& options, std::unique_ptr<KnnIndex> index)
    : model_(model), options_(options), index_(std::move(index)) {
  options_.Check();
  model_.Validate("model");
  if (!index_ && options_.index == "ivf") {
    // Coarse quantiser: k-means over (a stride sample of) the model's centres.
    const int m = model_.descriptors.rows, d = model_.params.dims;
    const int nlist = std::clamp(int(std::lround(std::sqrt(double(m)))), 1, 256);
    const int step = std::max(1, m / 4096);
    std::vector<float> sample;
    for (int i = 0; i < m; i += step)
      sample.insert(sample.end(), model_.descriptors.ptr<float>(i), model_.descriptors.ptr<float>(i) + d);
    std::vector<float> centroids;
    KMeans(sample.data(), int(sample.size() / std::size_t(d)), d, nlist, 8, 1, centroids);
    if (centroids.empty()) centroids.assign(std::size_t(d), 0.f);
    IvfOptions io;
    io.nprobe = options_.nprobe;
    index_ = std::make_unique<IvfIndex>(centroids.data(), centroids.size() / std::size_t(d), d, io);
  }
  if (!index_) index_ = MakeIndexByName(options_.index);
  const std::vector<std::int32_t> place = LocationPlaces(model_);
  places_.resize(model_.labels.size());
  for (std::size_t i = 0; i < places_.size(); ++i) places_[i] = place[model_.labels[i]];
  std::vector<std::vector<int>> location_rows(model_.locations.size());  // per location: its centres' rows
  for (std::size_t i = 0; i < model_.labels.size(); ++i) location_rows[model_.labels[i]].push_back(int(i));
  location_blocks_.assign(model_.locations.size(), {});
  const int dims = model_.descriptors.cols;
  for (std::size_t l = 0; l < location_rows.size(); ++l) {
    const std::vector<int>& rows = location_rows[l];
    if (rows.empty()) continue;
    const std::size_t nb = (rows.size() + 7) / 8;
    std::vector<float>& blk = location_blocks_[l];
    blk.resize(nb * std::size_t(dims) * 8);
    for (std::size_t j = 0; j < nb * 8; ++j) {
      const float* c = model_.descriptors.ptr<float>(rows[j < rows.size() ? j : 0]);
      for (int k = 0; k < dims; ++k) blk[((j / 8) * std::size_t(dims) + std::size_t(k)) * 8 + j % 8] = c[k];
    }
  }
  index_->Build(model_.descriptors.ptr<float>(), std::size_t(model_.descriptors.rows), model_.params.dims,
                places_.data());
}

FeatureOptions QueryFeatureOptions(const ModelParams& p, int max_points, int grid_cells, float grid_share) {
  FeatureOptions fo;
  fo.detector.grid_cells = grid_cells;
  fo.detector.grid_share = grid_share;
  fo.smooth_sigma = p.smooth_sigma;
  fo.detector.max_points = max_points;
  fo.detector.min_strength = p.min_strength;
  fo.detector.relative_threshold = p.relative_threshold;
  fo.detector.min_distance = p.min_distance;
  fo.detector.block_size = p.block_size;
  fo.describer.patch_size = p.patch_size;
  fo.describer.dims = p.dims;
  fo.describer.orient = p.orient;
  fo.describer.orientation_radius = p.orientation_radius;
  return fo;
}

// Nearest centre and nearest centre of another location for each descriptor,
// then the ratio test (on L2 distances; the index returns squared ones).
void Matcher::SearchAndFilter(const Features& f, std::size_t first, MatchResult& r) const {
  Timer t;
  const int n = int(f.keypoints.size() - first);
  std::vector<Neighbor> nn(2 * std::size_t(n));
  const float hint = options_.dynamic_goal > 0 ? options_.ratio_max : options_.ratio;
  if (n > 0) index_->SearchTwoDistinctBatch(f.descriptors.ptr<float>(int(first)), std::size_t(n), nn.data(), hint);
  float ratio = options_.ratio;
  const int checks = options_.dynamic_goal > 0 ? options_.dynamic_checks : 1;
  const std::size_t kept_before = r.matches.size();
  for (int i = 0; i < n; ++i) {
    if (options_.dynamic_goal > 0 && i > 0 && i % std::max(1, n / checks) == 0) {
      // Expected count so far if we are on track for the goal; move the ratio toward it.
      const double expected = double(options_.dynamic_goal) * i / n;
      const double have = double(r.matches.size() - kept_before);
      if (have < 0.8 * expected) ratio = std::min(options_.ratio_max, ratio + 0.05f);
      else if (have > 1.25 * expected) ratio = std::max(options_.ratio_min, ratio - 0.05f);
    }
    const Neighbor& a = nn[2 * i];
    const Neighbor& b = nn[2 * i + 1];
    if (a.id < 0) continue;
    const float d1 = std::sqrt(a.distance);
    const float d2 = b.id < 0 ? std::numeric_limits<float>::infinity() : std::sqrt(b.distance);
    if (!(d1 < ratio * d2)) continue;
    const int location = model_.labels[a.id];
    const auto& loc = model_.locations[location];
    const auto& kp = f.keypoints[first + i];
    r.matches.push_back({{loc.x, loc.y}, {kp.x, kp.y}, d1, d2 > 0 ? d1 / d2 : 0.f, location, false});
  }
  r.final_ratio = ratio;
  r.time.search_ms += t.ElapsedMs();
}

int CvMethod(RobustMethod m) {
  switch (m) {
    case RobustMethod::kRansac: return cv::RANSAC;
    case RobustMethod::kFast: return cv::USAC_FAST;
    case RobustMethod::kMagsac: return cv::USAC_MAGSAC;
    case RobustMethod::kProsac: return cv::USAC_PROSAC;
    case RobustMethod::kAccurate: break;
  }
  return cv::USAC_ACCURATE;
}

cv::UsacParams ProsacParams(const MatchOptions& o) {
  cv::UsacParams p;
  p.confidence = o.ransac_confidence;
  p.isParallel = false;
  p.loIterations = 10;
  p.loMethod = cv::LOCAL_OPTIM_GC;
  p.loSampleSize = 14;
  p.maxIterations = o.ransac_iterations;
  p.neighborsSearch = cv::NEIGH_GRID;
  p.randomGeneratorState = 0;
  p.sampler = cv::SAMPLING_PROSAC;
  p.score = cv::SCORE_METHOD_MSAC;
  p.threshold = o.ransac_threshold;
  return p;
}

GeometryFit FitGeometry(const std::vector<cv::Point2f>& src, const std::vector<cv::Point2f>& dst, const MatchOptions& o) {
  GeometryFit g;
  cv::Mat H;
  if (o.geometry == GeometryModel::kHomography) {
    if (o.robust == RobustMethod::kProsac)
      H = cv::findHomography(src, dst, g.mask, ProsacParams(o));
    else
      H = cv::findHomography(src, dst, CvMethod(o.robust), o.ransac_threshold, g.mask, o.ransac_iterations,
                             o.ransac_confidence);
  } else {
    cv::Mat A = o.robust == RobustMethod::kProsac
                    ? cv::estimateAffine2D(src, dst, g.mask, ProsacParams(o))
                    : cv::estimateAffine2D(src, dst, g.mask, CvMethod(o.robust), o.ransac_threshold,
                                           std::size_t(o.ransac_iterations), o.ransac_confidence, 10);
    if (!A.empty()) {
      H = cv::Mat::eye(3, 3, CV_64F);
      A.copyTo(H.rowRange(0, 2));
    }
  }
  if (H.empty()) return g;
  g.ok = true;
  g.homography = cv::Matx33d(H.ptr<double>());
  for (std::size_t i = 0; i < g.mask.size() && i < src.size(); ++i) g.inliers += g.mask[i] != 0;
  return g;
}

std::array<cv::Point2f, 4> ProjectOutline(const cv::Matx33d& H, int width, int height) {
  const float w = float(width - 1), h = float(height - 1);
  std::vector<cv::Point2f> corners = {{0, 0}, {w, 0}, {w, h}, {0, h}}, out;
  cv::perspectiveTransform(corners, out, cv::Mat(H));
  return {out[0], out[1], out[2], out[3]};
}

void Matcher::QueryPoints::SetFrame(const Describer& d, const cv::Mat& smoothed_frame,
                                    const std::vector<Keypoint>& keypoints) {
  Timer t;
  describer = &d;
  dims = d.dims();
  smoothed = smoothed_frame;
  kps = keypoints;
  if (!kps.empty()) prepared = d.Prepare(smoothed);
  pts.clear();
  for (const auto& k : kps) pts.emplace_back(k.x, k.y);
  desc.assign(pts.size() * std::size_t(dims), 0.f);
  ready.assign(pts.size(), 0);
  describe_ms += t.ElapsedMs();
}

void Matcher::QueryPoints::Describe(const std::vector<int>& idx) {
  Timer t;
  std::vector<int> todo;
  for (const int i : idx)
    if (!ready[std::size_t(i)]) todo.push_back(i);
  if (todo.empty()) return;
  std::vector<Keypoint> batch;
  batch.reserve(todo.size());
  for (const int i : todo) batch.push_back(kps[std::size_t(i)]);
  std::vector<float> out(todo.size() * std::size_t(dims));
  describer->Compute(smoothed, prepared, batch, out.data());
  for (std::size_t k = 0; k < todo.size(); ++k) {
    std::copy_n(&out[k * std::size_t(dims)], dims, &desc[std::size_t(todo[k]) * std::size_t(dims)]);
    ready[std::size_t(todo[k])] = 1;
  }
  describe_ms += t.ElapsedMs();
}

void Matcher::QueryPoints::Add(const Features& f) {
  for (const auto& k : f.keypoints) pts.emplace_back(k.x, k.y);
  if (f.descriptors.rows)
    desc.insert(desc.end(), f.descriptors.ptr<float>(), f.descriptors.ptr<float>() + f.descriptors.total());
  ready.resize(pts.size(), 1);
}

void Matcher::Verify(MatchResult& r, QueryPoints& q) const {
  Timer t;
  const double described_before = q.describe_ms;
  r.found = false;
  r.inliers = 0;
  r.support = 0;
  for (auto& m : r.matches) m.inlier = false;
  const int minimal = options_.geometry == GeometryModel::kHomography ? 4 : 3;
  if (int(r.matches.size()) >= std::max(minimal, options_.min_inliers)) {
    // PROSAC draws from the front: most distinctive (lowest ratio) first.
    std::vector<int> order(r.matches.size());
    std::iota(order.begin(), order.end(), 0);
    if (options_.robust == RobustMethod::kProsac)
      std::stable_sort(order.begin(), order.end(),
                       [&](int a, int b) { return r.matches[a].ratio < r.matches[b].ratio; });
    std::vector<cv::Point2f> src, dst;
    src.reserve(r.matches.size());
    dst.reserve(r.matches.size());
    for (int i : order) {
      src.push_back(r.matches[i].object);
      dst.push_back(r.matches[i].query);
    }
    const GeometryFit g = FitGeometry(src, dst, options_);
    if (g.ok) {
      const std::array<cv::Point2f, 4> quad = ProjectOutline(g.homography, model_.object_width, model_.object_height);
      if (g.inliers >= options_.min_inliers && IsPlausibleOutline(quad)) {
        r.found = true;
        r.homography = g.homography;
        r.outline = quad;
        r.inliers = g.inliers;
        r.support = g.inliers;
        for (std::size_t k = 0; k < g.mask.size() && k < order.size(); ++k) r.matches[order[k]].inlier = g.mask[k] != 0;
      }
    }
  }
  if (r.found && options_.refine) Refine(r, q);
  // Points the refinement described count as description.
  const double described = q.describe_ms - described_before;
  r.time.describe_ms += described;
  r.time.verify_ms += t.ElapsedMs() - described;
}

void Matcher::Refine(MatchResult& r, QueryPoints& q) const {
  const int dims = model_.params.dims;
  const int nq = int(q.pts.size());
  if (nq == 0) return;
  // Descriptor distance the fit's inliers reach: a guided pair must do as well.
  std::vector<float> inlier_d;
  for (const auto& m : r.matches)
    if (m.inlier) inlier_d.push_back(m.distance);
  if (inlier_d.size() < 4) return;
  std::sort(inlier_d.begin(), inlier_d.end());
  const float tau = inlier_d[std::min(inlier_d.size() - 1, std::size_t(0.8 * double(inlier_d.size())))];
  // Query points on a grid of cells of the search radius.
  const float R = options_.refine_radius;
  float xmax = 0, ymax = 0;
  for (const auto& p : q.pts) {
    xmax = std::max(xmax, p.x);
    ymax = std::max(ymax, p.y);
  }
  const int gw = int(xmax / R) + 2, gh = int(ymax / R) + 2;
  // As linked lists (head per cell, next per point): a vector per cell cost
  // thousands of allocations a frame. The order within a cell is immaterial.
  std::vector<int> head(std::size_t(gw) * gh, -1), next_in_cell(std::size_t(nq), -1);
  for (int i = 0; i < nq; ++i)
    if (q.pts[i].x >= 0 && q.pts[i].y >= 0) {
      int& h = head[std::size_t(int(q.pts[i].y / R)) * gw + int(q.pts[i].x / R)];
      next_in_cell[std::size_t(i)] = h;
      h = i;
    }
  // Where the homography puts each location (those it can pair).
  const cv::Matx33d& H = r.homography;
  const int nloc = int(model_.locations.size());
  std::vector<cv::Point2f> proj(static_cast<std::size_t>(nloc));
  std::vector<char> on(static_cast<std::size_t>(nloc), 0);
  float bx0 = std::numeric_limits<float>::infinity(), by0 = bx0, bx1 = -bx0, by1 = -bx0;
  for (int l = 0; l < nloc; ++l) {
    const auto& L = model_.locations[l];
    const double w = H(2, 0) * L.x + H(2, 1) * L.y + H(2, 2);
    if (!(w > 0)) continue;
    const float px = float((H(0, 0) * L.x + H(0, 1) * L.y + H(0, 2)) / w);
    const float py = float((H(1, 0) * L.x + H(1, 1) * L.y + H(1, 2)) / w);
    if (!(px >= -R && py >= -R && px <= xmax + R && py <= ymax + R)) continue;
    proj[std::size_t(l)] = {px, py};
    on[std::size_t(l)] = 1;
    bx0 = std::min(bx0, px);
    by0 = std::min(by0, py);
    bx1 = std::max(bx1, px);
    by1 = std::max(by1, py);
  }
  // Only points within R of a projected location can pair: describe those
  // of the frame's points that are not described yet.
  if (std::find(q.ready.begin(), q.ready.end(), 0) != q.ready.end()) {
    std::vector<int> near;
    for (int i = 0; i < nq; ++i)
      if (!q.ready[std::size_t(i)] && q.pts[i].x >= bx0 - R && q.pts[i].x <= bx1 + R && q.pts[i].y >= by0 - R &&
          q.pts[i].y <= by1 + R)
        near.push_back(i);
    q.Describe(near);
  }
  // Each location: the best query point near where the homography puts it.
  std::vector<float> best_d(nq, std::numeric_limits<float>::infinity());
  std::vector<int> best_loc(nq, -1);
  for (int l = 0; l < nloc; ++l) {
    if (!on[std::size_t(l)]) continue;
    const float px = proj[std::size_t(l)].x, py = proj[std::size_t(l)].y;
    const int cx = int(std::floor(px / R)), cy = int(std::floor(py / R));
    for (int yy = std::max(0, cy - 1); yy <= std::min(gh - 1, cy + 1); ++yy)
      for (int xx = std::max(0, cx - 1); xx <= std::min(gw - 1, cx + 1); ++xx)
        for (int i = head[std::size_t(yy) * gw + xx]; i >= 0; i = next_in_cell[std::size_t(i)]) {
          const float dx = q.pts[i].x - px, dy = q.pts[i].y - py;
          if (dx * dx + dy * dy > R * R || !q.ready[std::size_t(i)]) continue;
          const float* qd = &q.desc[std::size_t(i) * dims];
          float dmin = std::numeric_limits<float>::infinity();
          // Eight centres at a time, one per lane: each lane sums its
          // dimensions in order, as a plain loop over one centre would, so
          // the distances are the same values (and the loop vectorises).
          const std::vector<float>& blk = location_blocks_[l];
#if defined(__SSE2__)
          // (SSE2, the x86-64 baseline: separate multiply and add, as the
          // scalar code compiles without FMA.)
          __m128 m4 = _mm_set1_ps(dmin);
          for (std::size_t o = 0; o < blk.size(); o += std::size_t(dims) * 8) {
            __m128 s0 = _mm_setzero_ps(), s1 = _mm_setzero_ps();
            const float* c = blk.data() + o;
            for (int k = 0; k < dims; ++k) {
              const __m128 qk = _mm_set1_ps(qd[k]);
              const __m128 e0 = _mm_sub_ps(qk, _mm_loadu_ps(c + k * 8)), e1 = _mm_sub_ps(qk, _mm_loadu_ps(c + k * 8 + 4));
              s0 = _mm_add_ps(s0, _mm_mul_ps(e0, e0));
              s1 = _mm_add_ps(s1, _mm_mul_ps(e1, e1));
            }
            m4 = _mm_min_ps(m4, _mm_min_ps(s0, s1));
          }
          alignas(16) float m[4];
          _mm_store_ps(m, m4);
          dmin = std::min(std::min(m[0], m[1]), std::min(m[2], m[3]));
#else
          for (std::size_t o = 0; o < blk.size(); o += std::size_t(dims) * 8) {
            float s8[8] = {0, 0, 0, 0, 0, 0, 0, 0};
            const float* c = blk.data() + o;
            for (int k = 0; k < dims; ++k)
              for (int j = 0; j < 8; ++j) {
                const float e = qd[k] - c[k * 8 + j];
                s8[j] += e * e;
              }
            for (int j = 0; j < 8; ++j) dmin = std::min(dmin, s8[j]);
          }
#endif
          const float d = std::sqrt(dmin);
          if (d <= tau && d < best_d[i]) {
            best_d[i] = d;
            best_loc[i] = l;
          }
        }
  }
  std::vector<cv::Point2f> src, dst;
  for (int i = 0; i < nq; ++i)
    if (best_loc[i] >= 0) {
      src.emplace_back(model_.locations[best_loc[i]].x, model_.locations[best_loc[i]].y);
      dst.push_back(q.pts[i]);
    }
  // The fit's own inliers always take part.
  for (const auto& m : r.matches)
    if (m.inlier) {
      src.push_back(m.object);
      dst.push_back(m.query);
    }
  if (int(src.size()) < r.inliers + 4) return;  // nothing gained
  // Least squares, then drop what is off by more than the RANSAC threshold, twice.
  cv::Matx33d Hr = H;
  const double thr2 = options_.ransac_threshold * options_.ransac_threshold;
  std::vector<cv::Point2f> s2, d2;
  std::vector<char> kept(src.size(), 0), kept_before;
  int support = 0;
  for (int it = 0; it < 3; ++it) {
    s2.clear();
    d2.clear();
    for (std::size_t i = 0; i < src.size(); ++i) {
      const cv::Vec3d p = Hr * cv::Vec3d(src[i].x, src[i].y, 1);
      const double ex = p[0] / p[2] - dst[i].x, ey = p[1] / p[2] - dst[i].y;
      kept[i] = ex * ex + ey * ey <= thr2;
      if (kept[i]) {
        s2.push_back(src[i]);
        d2.push_back(dst[i]);
      }
    }
    support = int(s2.size());
    if (support < std::max(8, r.inliers)) return;
    // The same pairs as the last fit: refitting would give the same homography.
    if (kept == kept_before) break;
    kept_before = kept;
    cv::Mat Hn;
    if (options_.geometry == GeometryModel::kHomography) {
      cv::Matx33d Hf;
      if (FitHomographyLeastSquares(s2, d2, Hr, Hf)) Hn = cv::Mat(Hf, true);
    } else {
      cv::Mat A = cv::estimateAffine2D(s2, d2, cv::noArray(), cv::LMEDS);
      if (!A.empty()) {
        Hn = cv::Mat::eye(3, 3, CV_64F);
        A.copyTo(Hn.rowRange(0, 2));
      }
    }
    if (Hn.empty()) return;
    Hr = cv::Matx33d(Hn.ptr<double>());
  }
  const std::array<cv::Point2f, 4> quad = ProjectOutline(Hr, model_.object_width, model_.object_height);
  if (!IsPlausibleOutline(quad)) return;
  // Keep the refined homography if the fit's matches still agree with it.
  int inl = 0;
  std::vector<char> flag(r.matches.size(), 0);
  for (std::size_t i = 0; i < r.matches.size(); ++i) {
    const auto& m = r.matches[i];
    const cv::Vec3d p = Hr * cv::Vec3d(m.object.x, m.object.y, 1);
    const double ex = p[0] / p[2] - m.query.x, ey = p[1] / p[2] - m.query.y;
    flag[i] = ex * ex + ey * ey <= thr2;
    inl += flag[i];
  }
  if (inl < options_.min_inliers || inl < 0.8 * r.inliers) return;
  r.homography = Hr;
  r.outline = quad;
  r.inliers = inl;
  r.support = support;
  for (std::size_t i = 0; i < r.matches.size(); ++i) r.matches[i].inlier = flag[i];
}

namespace {

// Maps the query side of a result from an image scaled by `f` (pixel centres)
// back to the frame: H' = S^-1 H, matches and outline alike.
void ScaleQuerySide(MatchResult& r, double f, int object_w, int object_h) {
  const double a = 1.0 / f, b = 0.5 / f - 0.5;
  const cv::Matx33d S(a, 0, b, 0, a, b, 0, 0, 1);
  for (auto& m : r.matches) m.query = {float(m.query.x * a + b), float(m.query.y * a + b)};
  if (r.found) {
    r.homography = S * r.homography;
    r.homography *= 1.0 / r.homography(2, 2);
    r.outline = ProjectOutline(r.homography, object_w, object_h);
  }
}

void AddTime(MatchTiming& a, const MatchTiming& b) {
  a.smooth_ms += b.smooth_ms;
  a.detect_ms += b.detect_ms;
  a.describe_ms += b.describe_ms;
  a.search_ms += b.search_ms;
  a.verify_ms += b.verify_ms;
}

// The better of two results: found beats not found, then more inliers.
// The first n of `kps` (strongest first) in round-robin order over a grid of
// `cells` cells along the longer side, and the rest: a subset that covers the
// frame as the full set does.
void SpreadSplit(const std::vector<Keypoint>& kps, cv::Size size, int cells, int n, std::vector<int>& first,
                 std::vector<int>& rest) {
  const double side = double(std::max(size.width, size.height)) / std::max(1, cells);
  const int cw = std::max(1, int(std::ceil(size.width / side))), ch = std::max(1, int(std::ceil(size.height / side)));
  std::vector<std::vector<int>> bucket(std::size_t(cw) * ch);
  for (int i = 0; i < int(kps.size()); ++i) {
    const int cx = std::clamp(int(kps[i].x / side), 0, cw - 1), cy = std::clamp(int(kps[i].y / side), 0, ch - 1);
    bucket[std::size_t(cy) * cw + cx].push_back(i);
  }
  std::vector<char> in(kps.size(), 0);
  first.clear();
  rest.clear();
  for (std::size_t k = 0; int(first.size()) < n; ++k) {
    bool any = false;
    for (const auto& b : bucket)
      if (k < b.size() && int(first.size()) < n) {
        first.push_back(b[k]);
        in[b[k]] = 1;
        any = true;
      }
    if (!any) break;
  }
  for (int i = 0; i < int(kps.size()); ++i)
    if (!in[i]) rest.push_back(i);
}

// Smaller over larger local scale of H at the object's centre: cos(tilt) for
// a plane seen from afar, 1 for a frontal view (0 when degenerate).
double Anisotropy(const cv::Matx33d& H, int w, int h) {
  const cv::Vec2d sc = LocalScales(H, {0.5 * (w - 1), 0.5 * (h - 1)});
  return sc[1] > 0 && std::isfinite(sc[1]) ? sc[0] / sc[1] : 0;
}

bool Better(const MatchResult& a, const MatchResult& b) {
  if (a.found != b.found) return a.found;
  return a.inliers > b.inliers;
}

}  // namespace

MatchResult Matcher::Match(const cv::Mat& gray) const {
  CV_Assert(gray.type() == CV_8UC1);
  const int side = std::max(gray.cols, gray.rows);
  // Upsampling (tiny targets) only where no finer image exists and it stays cheap.
  if (options_.working_size <= 0 || side <= options_.working_size) return MatchAt(gray, true, side <= 1280);

  // A large frame: search it at the working size first; if the target is not
  // there, it may be too small for that size, so search twice as fine (up to
  // the frame itself). The answer is in the frame's pixels.
  MatchResult best;
  MatchTiming time;
  int keypoints = 0;
  bool first = true;
  for (double f = double(options_.working_size) / side;; f = std::min(1.0, 2 * f)) {
    Timer t;
    const cv::Mat img = ScaleFrameDown(gray, f);
    const double fx = double(img.cols) / gray.cols;
    const double resample_ms = t.ElapsedMs();
    // Steep views are simulated at the working size only (their cost grows with the pixels).
    MatchResult r = MatchAt(img, /*tilt=*/first, /*upsample=*/false);
    first = false;
    r.time.smooth_ms += resample_ms;
    AddTime(time, r.time);
    keypoints += r.keypoints;
    ScaleQuerySide(r, fx, model_.object_width, model_.object_height);
    if (Better(r, best) || best.keypoints == 0) best = std::move(r);
    if (best.found || f >= 1.0) break;
  }
  best.time = time;
  best.keypoints = keypoints;
  return best;
}

MatchResult Matcher::MatchAt(const cv::Mat& gray, bool tilt, bool upsample) const {
  MatchResult r;
  FeatureOptions fo = QueryFeatureOptions(model_.params, options_.max_points, options_.grid_cells, options_.grid_share);
  const DetectedFrame d = DetectFeatures(gray, fo);
  r.keypoints = int(d.keypoints.size());
  r.time.smooth_ms = d.smooth_ms;
  r.time.detect_ms = d.detect_ms;
  // The frame's points are described as they are needed: the first pass's,
  // then the rest if that pass is not enough, or only those on the target
  // when refinement wants them.
  const Describer describer(fo.describer);
  QueryPoints q;
  q.SetFrame(describer, d.smoothed, d.keypoints);
  r.time.describe_ms += q.describe_ms;
  auto described = [&](const std::vector<int>& idx) {
    const double before = q.describe_ms;
    q.Describe(idx);
    r.time.describe_ms += q.describe_ms - before;
    Features s;
    s.keypoints.reserve(idx.size());
    s.descriptors.create(int(idx.size()), q.dims, CV_32F);
    for (int k = 0; k < int(idx.size()); ++k) {
      s.keypoints.push_back(d.keypoints[std::size_t(idx[k])]);
      std::copy_n(&q.desc[std::size_t(idx[k]) * std::size_t(q.dims)], q.dims, s.descriptors.ptr<float>(k));
    }
    return s;
  };
  if (options_.first_pass_points > 0 && r.keypoints > options_.first_pass_points) {
    std::vector<int> first, rest;
    SpreadSplit(d.keypoints, gray.size(), options_.grid_cells, options_.first_pass_points, first, rest);
    SearchAndFilter(described(first), 0, r);
    Verify(r, q);
    if (r.found && r.inliers >= options_.retry_below_inliers) return r;
    SearchAndFilter(described(rest), 0, r);
  } else {
    std::vector<int> all(d.keypoints.size());
    std::iota(all.begin(), all.end(), 0);
    SearchAndFilter(described(all), 0, r);
  }
  Verify(r, q);
  if (r.found && r.inliers >= options_.retry_below_inliers) return r;

  // One more set of points from a resampled copy of the frame (`to_frame`
  // maps its pixel coordinates back), searched and verified with the rest.
  auto add_pass = [&](int interpolation, cv::Size size, int points, auto to_frame) {
    Timer tr;
    cv::Mat img;
    cv::resize(gray, img, size, 0, 0, interpolation);
    r.time.smooth_ms += tr.ElapsedMs();
    fo.detector.max_points = points;
    Features g = ExtractFeatures(img, fo);
    for (auto& k : g.keypoints) {
      k.x = to_frame(k.x);
      k.y = to_frame(k.y);
    }
    r.time.smooth_ms += g.smooth_ms;
    r.time.detect_ms += g.detect_ms;
    r.time.describe_ms += g.describe_ms;
    r.keypoints += int(g.keypoints.size());
    SearchAndFilter(g, 0, r);
    if (options_.refine) q.Add(g);
    Verify(r, q);
  };

  // Not found, or weakly: the target may appear larger than the trained view
  // range. Add points from half resolution, verify again, keep the better.
  if (options_.half_res_points > 0 && gray.cols >= 64 && gray.rows >= 64) {
    const MatchResult first = r;
    // half-resolution pixel centres at full resolution
    add_pass(cv::INTER_AREA, cv::Size(gray.cols / 2, gray.rows / 2), options_.half_res_points,
             [](float v) { return 2 * v + 0.5f; });
    if (first.found && r.inliers <= first.inliers) {
      MatchTiming t = r.time;
      const int kps = r.keypoints;
      r = first;
      r.time = t;
      r.keypoints = kps;
    }
  }
  // Found, but weakly and as a steep view: the fit may rest on the near part
  // of the target, with the far corners off. The simulated tilts below see
  // the whole target less foreshortened; run them too and keep the better.
  const bool weak_steep = r.found && r.inliers < options_.retry_below_inliers && options_.steep_anisotropy > 0 &&
                          Anisotropy(r.homography, model_.object_width, model_.object_height) < options_.steep_anisotropy;
  if (r.found && !(tilt && weak_steep)) return r;

  // Not found: the target may be smaller than the smallest trained level
  // covers. Search the frame upsampled twice (its points mapped back).
  if (!r.found && upsample && options_.upsample_points > 0) {
    // double-resolution pixel centres at full resolution
    add_pass(cv::INTER_LINEAR, cv::Size(gray.cols * 2, gray.rows * 2), options_.upsample_points,
             [](float v) { return (v + 0.5f) / 2 - 0.5f; });
    if (r.found) return r;
  }
  if (!tilt || options_.tilt_directions <= 0 || options_.tilt_factors.empty() || gray.cols < 64 || gray.rows < 64) return r;

  // Still nothing: simulate steep views of the frame (ASIFT-style). For each
  // direction phi and factor t the frame is rotated by -phi, blurred along y
  // against aliasing, shrunk by sqrt(t) along y and stretched by sqrt(t)
  // along x: the target keeps its size in pixels while a tilt along y loses
  // a factor t of its anisotropy. Points found there are mapped back to the
  // frame. Each simulated view is verified alone (its matches are one
  // population); the best fit wins and is refined with every point.
  MatchResult best = r;
  FeatureOptions ft = fo;
  ft.detector.max_points = options_.tilt_points;
  for (float t : options_.tilt_factors) {
    const int dirs = options_.tilt_directions_grow
                         ? std::clamp(int(std::lround(options_.tilt_directions * double(t) / options_.tilt_factors[0])),
                                      options_.tilt_directions, 64)
                         : options_.tilt_directions;
    for (int k = 0; k < dirs; ++k) {
      Timer tw;
      const double phi = CV_PI * k / dirs;
      const double c = std::cos(phi), sn = std::sin(phi);
      // Rotation by -phi into a canvas holding the whole frame.
      double rx0 = 1e300, ry0 = 1e300, rx1 = -1e300, ry1 = -1e300;
      for (const cv::Vec2d& p : {cv::Vec2d(0, 0), cv::Vec2d(gray.cols - 1, 0), cv::Vec2d(0, gray.rows - 1),
                                 cv::Vec2d(gray.cols - 1, gray.rows - 1)}) {
        const double vx = c * p[0] + sn * p[1], vy = -sn * p[0] + c * p[1];
        rx0 = std::min(rx0, vx); ry0 = std::min(ry0, vy);
        rx1 = std::max(rx1, vx); ry1 = std::max(ry1, vy);
      }
      cv::Mat rot;
      if (k == 0) {
        rot = gray;
        rx0 = ry0 = 0;
      } else {
        const cv::Matx23d M(c, sn, -rx0, -sn, c, -ry0);
        cv::warpAffine(gray, rot, cv::Mat(M), cv::Size(int(std::ceil(rx1 - rx0)) + 1, int(std::ceil(ry1 - ry0)) + 1),
                       cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
      }
      const double st = std::sqrt(double(t));
      const double sigma = 0.8 * std::sqrt(st * st - 1.0);
      cv::Mat blurred, sim;
      cv::GaussianBlur(rot, blurred, cv::Size(1, 2 * int(std::ceil(3 * sigma)) + 1), 0.1, sigma, cv::BORDER_REPLICATE);
      cv::resize(blurred, sim,
                 cv::Size(std::max(8, int(std::lround(rot.cols * st))), std::max(8, int(std::lround(rot.rows / st)))), 0,
                 0, cv::INTER_LINEAR);
      r.time.smooth_ms += tw.ElapsedMs();
      Features h = ExtractFeatures(sim, ft);
      // Simulated pixel -> frame pixel: undo the resize (pixel centres), the canvas shift and the rotation.
      const double fx = double(rot.cols) / sim.cols, fy = double(rot.rows) / sim.rows;
      for (auto& kp : h.keypoints) {
        const double rx = (kp.x + 0.5) * fx - 0.5 + rx0, ry = (kp.y + 0.5) * fy - 0.5 + ry0;
        kp.x = float(c * rx - sn * ry);
        kp.y = float(sn * rx + c * ry);
      }
      r.time.smooth_ms += h.smooth_ms;
      r.time.detect_ms += h.detect_ms;
      r.time.describe_ms += h.describe_ms;
      r.keypoints += int(h.keypoints.size());
      MatchResult part;
      SearchAndFilter(h, 0, part);
      r.time.search_ms += part.time.search_ms;
      if (options_.refine) q.Add(h);
      QueryPoints none;
      Verify(part, none);
      r.time.verify_ms += part.time.verify_ms;
      if (part.found && (!best.found || part.inliers > best.inliers)) best = std::move(part);
    }
  }
  if (best.found) {
    const MatchTiming keep = r.time;
    const int kps = r.keypoints;
    r = std::move(best);
    r.time = keep;
    r.keypoints = kps;
    Timer tr;
    if (options_.refine) Refine(r, q);
    r.time.verify_ms += tr.ElapsedMs();
  }
  return r;
}

}  // namespace mvkp
