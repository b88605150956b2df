#include "mvkp/local/pair_match.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {
namespace {

cv::Point2f Project(const cv::Matx33d& H, cv::Point2f p) {
  const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
  return {float(v[0] / v[2]), float(v[1] / v[2])};
}

}  // namespace

void PairMatchOptions::Check() const {
  Require(ratio > 0 && ratio <= 1, ErrorCode::kInvalidArgument, "ratio must be in (0, 1]");
  Require(ransac_px > 0, ErrorCode::kInvalidArgument, "RANSAC threshold must be > 0 px");
  Require(min_inliers >= 4, ErrorCode::kInvalidArgument, "min inliers must be >= 4");
}

PairMatchResult MatchPair(const LocalFeatures& object, const LocalFeatures& query, const std::vector<NearestTwo>& nearest,
                          const PairMatchOptions& o) {
  o.Check();
  PairMatchResult r;
  for (const auto& n : nearest)
    if (n.best >= 0 && n.d1 < o.ratio * n.d2)
      r.matches.push_back({object.keypoints[n.best].pt, query.keypoints[n.query].pt, n.d1, false});
  Timer t;
  if (r.matches.size() >= 4) {
    std::vector<cv::Point2f> a, b;
    for (const auto& m : r.matches) {
      a.push_back(m.object);
      b.push_back(m.query);
    }
    cv::theRNG().state = 0x12345678;  // reproducible RANSAC
    std::vector<std::uint8_t> mask;
    const cv::Mat H = cv::findHomography(a, b, cv::RANSAC, o.ransac_px, mask, 2000, 0.995);
    if (!H.empty()) {
      for (std::size_t i = 0; i < r.matches.size(); ++i) r.matches[i].inlier = mask[i] != 0;
      r.inliers = int(std::count(mask.begin(), mask.end(), 1));
      if (r.inliers >= o.min_inliers) {
        r.found = true;
        r.homography = cv::Matx33d(H.ptr<double>());
      }
    }
  }
  r.verify_ms = t.ElapsedMs();
  return r;
}

std::vector<double> DefaultRatioSweep() {
  std::vector<double> r;
  for (int i = 0; i < 10; ++i) r.push_back(0.5 + 0.05 * i);
  return r;
}

PairEvaluation EvaluatePair(const LocalFeatures& object, const LocalFeatures& query, const std::vector<NearestTwo>& nearest,
                            const cv::Matx33d& H, cv::Size query_size, const std::vector<double>& ratios, double eps) {
  Require(eps > 0, ErrorCode::kInvalidArgument, "correctness threshold must be > 0 px");
  PairEvaluation e;
  // Correspondences: object keypoints whose true image lies in the query
  // image and has a query keypoint within eps (grid of eps-sized cells).
  const float cell = float(eps);
  const int gw = int(query_size.width / cell) + 2, gh = int(query_size.height / cell) + 2;
  std::vector<std::vector<int>> grid(std::size_t(gw) * gh);
  for (int i = 0; i < int(query.keypoints.size()); ++i) {
    const cv::Point2f p = query.keypoints[i].pt;
    const int gx = std::clamp(int(p.x / cell), 0, gw - 1), gy = std::clamp(int(p.y / cell), 0, gh - 1);
    grid[std::size_t(gy) * gw + gx].push_back(i);
  }
  for (const auto& kp : object.keypoints) {
    const cv::Point2f p = Project(H, kp.pt);
    if (!(p.x >= 0 && p.y >= 0 && p.x < query_size.width && p.y < query_size.height)) continue;
    const int gx = int(p.x / cell), gy = int(p.y / cell);
    bool hit = false;
    for (int y = std::max(0, gy - 1); y <= std::min(gh - 1, gy + 1) && !hit; ++y)
      for (int x = std::max(0, gx - 1); x <= std::min(gw - 1, gx + 1) && !hit; ++x)
        for (int q : grid[std::size_t(y) * gw + x])
          if (std::hypot(query.keypoints[q].pt.x - p.x, query.keypoints[q].pt.y - p.y) < eps) {
            hit = true;
            break;
          }
    e.correspondences += hit;
  }
  std::vector<char> ok(nearest.size());
  for (std::size_t i = 0; i < nearest.size(); ++i) {
    const auto& n = nearest[i];
    if (n.best < 0) continue;
    const cv::Point2f p = Project(H, object.keypoints[n.best].pt);
    const cv::Point2f q = query.keypoints[n.query].pt;
    ok[i] = std::hypot(p.x - q.x, p.y - q.y) < eps;
  }
  for (double r : ratios) {
    RatioPoint pt{r, 0, 0};
    for (std::size_t i = 0; i < nearest.size(); ++i)
      if (nearest[i].best >= 0 && nearest[i].d1 < r * nearest[i].d2) {
        ++pt.matches;
        pt.correct += ok[i];
      }
    e.sweep.push_back(pt);
  }
  return e;
}

}  // namespace mvkp
