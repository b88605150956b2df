#include "mvkp/match/matcher.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/index/ffva.h"

namespace mvkp {

void MatchOptions::Check() const {
  Require(max_points >= 4 && max_points <= 100000, ErrorCode::kInvalidArgument, "max points must be in 4..100000");
  Require(half_res_points >= 0 && half_res_points <= 100000, ErrorCode::kInvalidArgument,
          "half-resolution points must be in 0..100000");
  Require(retry_below_inliers >= 0, ErrorCode::kInvalidArgument, "retry threshold must be >= 0");
  Require(ratio > 0.f && ratio <= 1.f, ErrorCode::kInvalidArgument, "ratio must be in (0, 1]");
  Require(dynamic_goal >= 0, ErrorCode::kInvalidArgument, "dynamic goal must be >= 0");
  Require(dynamic_checks >= 1 && dynamic_checks <= 1000, ErrorCode::kInvalidArgument, "dynamic checks must be in 1..1000");
  Require(ratio_min > 0.f && ratio_min <= ratio_max && ratio_max <= 1.f, ErrorCode::kInvalidArgument,
          "dynamic ratio bounds must satisfy 0 < min <= max <= 1");
  Require(ransac_threshold > 0 && ransac_threshold <= 100, ErrorCode::kInvalidArgument, "RANSAC threshold must be in (0, 100]");
  Require(ransac_iterations >= 1 && ransac_iterations <= 1000000, ErrorCode::kInvalidArgument, "RANSAC iterations must be in 1..1e6");
  Require(ransac_confidence > 0 && ransac_confidence < 1, ErrorCode::kInvalidArgument, "RANSAC confidence must be in (0, 1)");
  Require(index == "exact" || index == "approx" || index == "brute", ErrorCode::kInvalidArgument,
          "index must be exact, approx or brute");
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

Matcher::Matcher(const Model& model, const MatchOptions& options, std::unique_ptr<KnnIndex> index)
    : model_(model), options_(options), index_(std::move(index)) {
  options_.Check();
  model_.Validate("model");
  if (!index_) index_ = MakeIndexByName(options_.index);
  index_->Build(model_.descriptors.ptr<float>(), std::size_t(model_.descriptors.rows), model_.params.dims,
                model_.labels.data());
}

FeatureOptions QueryFeatureOptions(const ModelParams& p, int max_points) {
  FeatureOptions fo;
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
    const auto& loc = model_.locations[a.label];
    const auto& kp = f.keypoints[first + i];
    r.matches.push_back({{loc.x, loc.y}, {kp.x, kp.y}, d1, a.label, false});
  }
  r.final_ratio = ratio;
  r.time.search_ms += t.ElapsedMs();
}

int CvMethod(RobustMethod m) {
  switch (m) {
    case RobustMethod::kRansac: return cv::RANSAC;
    case RobustMethod::kFast: return cv::USAC_FAST;
    case RobustMethod::kMagsac: return cv::USAC_MAGSAC;
    case RobustMethod::kAccurate: break;
  }
  return cv::USAC_ACCURATE;
}

GeometryFit FitGeometry(const std::vector<cv::Point2f>& src, const std::vector<cv::Point2f>& dst, const MatchOptions& o) {
  GeometryFit g;
  cv::Mat H;
  if (o.geometry == GeometryModel::kHomography) {
    H = cv::findHomography(src, dst, CvMethod(o.robust), o.ransac_threshold, g.mask, o.ransac_iterations,
                           o.ransac_confidence);
  } else {
    cv::Mat A = cv::estimateAffine2D(src, dst, g.mask, CvMethod(o.robust), o.ransac_threshold,
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

void Matcher::Verify(MatchResult& r) const {
  Timer t;
  r.found = false;
  r.inliers = 0;
  for (auto& m : r.matches) m.inlier = false;
  const int minimal = options_.geometry == GeometryModel::kHomography ? 4 : 3;
  if (int(r.matches.size()) >= std::max(minimal, options_.min_inliers)) {
    std::vector<cv::Point2f> src, dst;
    src.reserve(r.matches.size());
    dst.reserve(r.matches.size());
    for (const auto& m : r.matches) {
      src.push_back(m.object);
      dst.push_back(m.query);
    }
    const GeometryFit g = FitGeometry(src, dst, options_);
    if (g.ok) {
      const std::array<cv::Point2f, 4> quad = ProjectOutline(g.homography, model_.object_width, model_.object_height);
      if (g.inliers >= options_.min_inliers && IsPlausibleOutline(quad)) {
        r.found = true;
        r.homography = g.homography;
        r.outline = quad;
        r.inliers = g.inliers;
        for (std::size_t i = 0; i < g.mask.size() && i < r.matches.size(); ++i) r.matches[i].inlier = g.mask[i] != 0;
      }
    }
  }
  r.time.verify_ms += t.ElapsedMs();
}

MatchResult Matcher::Match(const cv::Mat& gray) const {
  CV_Assert(gray.type() == CV_8UC1);
  MatchResult r;
  FeatureOptions fo = QueryFeatureOptions(model_.params, options_.max_points);
  Features f = ExtractFeatures(gray, fo);
  r.keypoints = int(f.keypoints.size());
  r.time.smooth_ms = f.smooth_ms;
  r.time.detect_ms = f.detect_ms;
  r.time.describe_ms = f.describe_ms;
  SearchAndFilter(f, 0, r);
  Verify(r);
  if ((r.found && r.inliers >= options_.retry_below_inliers) || options_.half_res_points <= 0 || gray.cols < 64 ||
      gray.rows < 64)
    return r;

  // Not found, or weakly: the target may appear larger than the trained view
  // range. Add points from half resolution, verify again, keep the better.
  const MatchResult first = r;
  Timer th;
  cv::Mat half;
  cv::resize(gray, half, cv::Size(gray.cols / 2, gray.rows / 2), 0, 0, cv::INTER_AREA);
  r.time.smooth_ms += th.ElapsedMs();
  fo.detector.max_points = options_.half_res_points;
  Features g = ExtractFeatures(half, fo);
  for (auto& k : g.keypoints) {  // half-resolution pixel centres at full resolution
    k.x = 2 * k.x + 0.5f;
    k.y = 2 * k.y + 0.5f;
  }
  r.time.smooth_ms += g.smooth_ms;
  r.time.detect_ms += g.detect_ms;
  r.time.describe_ms += g.describe_ms;
  r.keypoints += int(g.keypoints.size());
  SearchAndFilter(g, 0, r);
  Verify(r);
  if (first.found && r.inliers <= first.inliers) {
    MatchTiming t = r.time;
    r = first;
    r.time = t;
  }
  return r;
}

}  // namespace mvkp
