#include "mvkp/track/tracker.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

void TrackerOptions::Check() const {
  auto req = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, std::string("tracker: ") + m); };
  req(max_points >= 4 && max_points <= 10000, "max points must be in 4..10000");
  req(quality_level > 0 && quality_level < 1, "quality level must be in (0, 1)");
  req(min_distance >= 0 && border >= 0, "min distance and border must be >= 0");
  req(pyramid_levels >= 0 && pyramid_levels <= 8, "pyramid levels must be in 0..8");
  req(window >= 5 && window <= 101, "window must be in 5..101");
  req(max_fb_error > 0, "forward-backward threshold must be > 0");
  req(ransac_threshold > 0 && ransac_threshold <= 50, "RANSAC threshold must be in (0, 50]");
  req(min_points >= 4 && min_points <= max_points, "min points must be in 4..max points");
  req(min_inlier_fraction >= 0 && min_inlier_fraction <= 1, "min inlier fraction must be in [0, 1]");
  req(reseed_below >= 0 && reseed_below <= 1, "re-seed fraction must be in [0, 1]");
  req(max_jump > 0 && max_area_change >= 1, "max jump must be > 0 and max area change >= 1");
  req(min_ncc >= 0 && min_ncc < 1, "min NCC must be in [0, 1)");
  req(redetect_every >= 0, "redetect-every must be >= 0");
}

TargetTracker::TargetTracker(const TrackerOptions& options) : options_(options) { options_.Check(); }

void TargetTracker::CheckFrame(const cv::Mat& gray, const char* what) const {
  Require(!gray.empty(), ErrorCode::kInvalidArgument, std::string("tracker ") + what + ": empty frame");
  Require(gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          std::string("tracker ") + what + ": frame must be 8-bit, one channel");
}

std::array<cv::Point2f, 4> TargetTracker::outline() const {
  return ProjectOutline(H_, object_size_.width, object_size_.height);
}

namespace {

bool Finite(const cv::Matx33d& H) {
  for (int i = 0; i < 9; ++i)
    if (!std::isfinite(H.val[i])) return false;
  return true;
}

double Area(const std::array<cv::Point2f, 4>& q) {
  return std::abs(cv::contourArea(std::vector<cv::Point2f>(q.begin(), q.end())));
}

cv::Rect Bounds(const std::array<cv::Point2f, 4>& q, cv::Size frame) {
  float x0 = q[0].x, x1 = q[0].x, y0 = q[0].y, y1 = q[0].y;
  for (const auto& p : q) {
    x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
    y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
  }
  const cv::Rect r(cv::Point(int(std::floor(std::max(x0, -1.f))), int(std::floor(std::max(y0, -1.f)))),
                   cv::Point(int(std::ceil(std::min(x1, float(frame.width + 1)))) + 1,
                             int(std::ceil(std::min(y1, float(frame.height + 1)))) + 1));
  return r & cv::Rect(cv::Point(0, 0), frame);
}

}  // namespace

bool TargetTracker::Start(const cv::Mat& gray, const cv::Matx33d& H, cv::Size object_size) {
  CheckFrame(gray, "start");
  Require(object_size.width > 0 && object_size.height > 0, ErrorCode::kInvalidArgument,
          "tracker start: object size must be positive");
  Require(Finite(H), ErrorCode::kInvalidArgument, "tracker start: homography is not finite");
  const auto quad = ProjectOutline(H, object_size.width, object_size.height);
  Require(IsPlausibleOutline(quad), ErrorCode::kInvalidArgument, "tracker start: implausible target outline");
  active_ = false;
  frame_size_ = gray.size();
  object_size_ = object_size;
  H_ = H;
  object_pts_.clear();
  frame_pts_.clear();
  inliers_ = 0;
  ncc_ = 1;
  prev_gray_ = gray.clone();
  if (Seed(prev_gray_, options_.max_points) < options_.min_points) return false;
  cv::buildOpticalFlowPyramid(prev_gray_, prev_pyr_, cv::Size(options_.window, options_.window), options_.pyramid_levels);
  SetReference(prev_gray_, H_);
  since_verified_ = 0;
  active_ = true;
  return true;
}

// Adds up to `wanted` corners inside the current outline (eroded by border),
// away from the points already tracked. Returns the number of points tracked.
int TargetTracker::Seed(const cv::Mat& gray, int wanted) {
  const auto quad = outline();
  const cv::Rect roi = Bounds(quad, gray.size());
  if (wanted <= 0 || roi.width < 8 || roi.height < 8) return int(object_pts_.size());
  cv::Mat mask(roi.size(), CV_8UC1, cv::Scalar(0));
  std::vector<cv::Point> poly;
  for (const auto& p : quad) poly.emplace_back(int(std::lround(p.x - roi.x)), int(std::lround(p.y - roi.y)));
  cv::fillConvexPoly(mask, poly, cv::Scalar(255));
  if (options_.border > 0) cv::polylines(mask, poly, true, cv::Scalar(0), 2 * options_.border + 1);
  const int r = std::max(1, int(std::lround(options_.min_distance)));
  for (const auto& p : frame_pts_)
    cv::circle(mask, cv::Point(int(std::lround(p.x - roi.x)), int(std::lround(p.y - roi.y))), r, cv::Scalar(0), -1);
  std::vector<cv::Point2f> corners;
  cv::goodFeaturesToTrack(gray(roi), corners, wanted, options_.quality_level, options_.min_distance, mask, 3);
  if (corners.empty()) return int(object_pts_.size());
  for (auto& c : corners) c += cv::Point2f(float(roi.x), float(roi.y));
  std::vector<cv::Point2f> obj;
  cv::perspectiveTransform(corners, obj, cv::Mat(H_.inv()));
  for (std::size_t i = 0; i < corners.size(); ++i) {
    if (!std::isfinite(obj[i].x) || !std::isfinite(obj[i].y)) continue;
    object_pts_.push_back(obj[i]);
    frame_pts_.push_back(corners[i]);
  }
  return int(object_pts_.size());
}

// The target region of a verified frame at half resolution, with its mask.
void TargetTracker::SetReference(const cv::Mat& gray, const cv::Matx33d& H) {
  ref_H_ = H;
  ref_patch_.release();
  ref_mask_.release();
  const auto quad = ProjectOutline(H, object_size_.width, object_size_.height);
  const cv::Rect roi = Bounds(quad, gray.size());
  if (roi.width < 16 || roi.height < 16) return;
  cv::resize(gray(roi), ref_patch_, cv::Size(roi.width / 2, roi.height / 2), 0, 0, cv::INTER_AREA);
  cv::GaussianBlur(ref_patch_, ref_patch_, cv::Size(5, 5), 1.0);
  // Reference pixel x -> patch pixel (x - roi.x - 0.5) / 2 (INTER_AREA by 2: pixel centres).
  ref_to_patch_ = cv::Matx33d(0.5, 0, -0.5 * roi.x - 0.25, 0, 0.5, -0.5 * roi.y - 0.25, 0, 0, 1);
  ref_mask_ = cv::Mat(ref_patch_.size(), CV_8UC1, cv::Scalar(0));
  std::vector<cv::Point2f> q(quad.begin(), quad.end()), qp;
  cv::perspectiveTransform(q, qp, cv::Mat(ref_to_patch_));
  std::vector<cv::Point> poly;
  for (const auto& p : qp) poly.emplace_back(int(std::lround(p.x)), int(std::lround(p.y)));
  cv::fillConvexPoly(ref_mask_, poly, cv::Scalar(255));
  cv::polylines(ref_mask_, poly, true, cv::Scalar(0), 5);  // keep the background at the edge out
}

// Normalised cross-correlation between the reference patch and this frame
// warped back onto it by H (object -> frame), over the target pixels both show.
double TargetTracker::Appearance(const cv::Mat& gray, const cv::Matx33d& H) const {
  if (ref_patch_.empty()) return 1;  // target too small when verified: nothing to compare
  // patch -> reference frame -> object -> this frame
  const cv::Matx33d M = H * ref_H_.inv() * ref_to_patch_.inv();
  if (!Finite(M)) return 0;
  cv::Mat warped, valid;
  cv::warpPerspective(gray, warped, cv::Mat(M), ref_patch_.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT);
  cv::Mat ones(gray.size(), CV_8UC1, cv::Scalar(255));
  cv::warpPerspective(ones, valid, cv::Mat(M), ref_patch_.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP,
                      cv::BORDER_CONSTANT);
  cv::GaussianBlur(warped, warped, cv::Size(5, 5), 1.0);
  cv::bitwise_and(valid, ref_mask_, valid);
  cv::erode(valid, valid, cv::Mat());  // the blur mixed the border in
  const int n = cv::countNonZero(valid);
  if (n < 64 || n < cv::countNonZero(ref_mask_) / 10) return 1;  // too little of the target in view to judge
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(ref_patch_, ma, sa, valid);
  cv::meanStdDev(warped, mb, sb, valid);
  if (sa[0] < 2 || sb[0] < 2) return 0;  // uniform: nothing of the target
  cv::Mat a, b;
  ref_patch_.convertTo(a, CV_32F, 1, -ma[0]);
  warped.convertTo(b, CV_32F, 1, -mb[0]);
  const double cov = cv::mean(a.mul(b), valid)[0];
  return cov / (sa[0] * sb[0]);
}

bool TargetTracker::Update(const cv::Mat& gray, cv::Matx33d* H_out) {
  CheckFrame(gray, "update");
  Require(active_, ErrorCode::kInvalidArgument, "tracker update: not tracking (call Start first)");
  Require(gray.size() == frame_size_, ErrorCode::kInvalidArgument, "tracker update: frame size changed");
  const cv::Size win(options_.window, options_.window);
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  cv::Mat cur = gray.clone();  // the caller may reuse its buffer
  std::vector<cv::Mat> pyr;
  cv::buildOpticalFlowPyramid(cur, pyr, win, options_.pyramid_levels);
  auto fail = [&] {
    active_ = false;
    return false;
  };
  if (frame_pts_.empty()) return fail();
  std::vector<cv::Point2f> next, back = frame_pts_;
  std::vector<uchar> st, st2;
  std::vector<float> err;
  cv::calcOpticalFlowPyrLK(prev_pyr_, pyr, frame_pts_, next, st, err, win, options_.pyramid_levels, crit);
  cv::calcOpticalFlowPyrLK(pyr, prev_pyr_, next, back, st2, err, win, options_.pyramid_levels, crit,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> obj, pts;
  const float fb2 = float(options_.max_fb_error * options_.max_fb_error);
  const cv::Rect2f inside(0, 0, float(gray.cols - 1), float(gray.rows - 1));
  for (std::size_t i = 0; i < frame_pts_.size(); ++i) {
    const cv::Point2f d = back[i] - frame_pts_[i];
    if (!st[i] || !st2[i] || d.dot(d) > fb2 || !inside.contains(next[i])) continue;
    obj.push_back(object_pts_[i]);
    pts.push_back(next[i]);
  }
  inliers_ = 0;
  if (int(pts.size()) < options_.min_points) return fail();
  MatchOptions mo;
  mo.robust = options_.robust;
  mo.ransac_threshold = options_.ransac_threshold;
  mo.ransac_iterations = 500;
  mo.ransac_confidence = 0.995;
  cv::theRNG().state = 0x12345678;  // reproducible RANSAC
  const GeometryFit g = FitGeometry(obj, pts, mo);
  if (!g.ok || !Finite(g.homography)) return fail();
  inliers_ = g.inliers;
  if (g.inliers < options_.min_points || g.inliers < options_.min_inlier_fraction * double(pts.size())) return fail();
  const auto before = outline();
  const auto after = ProjectOutline(g.homography, object_size_.width, object_size_.height);
  if (!IsPlausibleOutline(after)) return fail();
  const double diag = std::max(cv::norm(before[2] - before[0]), cv::norm(before[3] - before[1]));
  for (int k = 0; k < 4; ++k)
    if (cv::norm(after[k] - before[k]) > options_.max_jump * diag) return fail();
  const double a0 = Area(before), a1 = Area(after);
  if (a1 > a0 * options_.max_area_change || a1 * options_.max_area_change < a0) return fail();
  ncc_ = Appearance(cur, g.homography);
  if (options_.min_ncc > 0 && ncc_ < options_.min_ncc) return fail();

  object_pts_.clear();
  frame_pts_.clear();
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (g.mask[i]) {
      object_pts_.push_back(obj[i]);
      frame_pts_.push_back(pts[i]);
    }
  H_ = g.homography;
  prev_pyr_ = std::move(pyr);
  prev_gray_ = cur;
  ++since_verified_;
  if (int(object_pts_.size()) < options_.reseed_below * options_.max_points)
    Seed(prev_gray_, options_.max_points - int(object_pts_.size()));
  if (H_out) *H_out = H_;
  return true;
}

void TargetTracker::Confirm() {
  if (!active_) return;
  SetReference(prev_gray_, H_);
  since_verified_ = 0;
}

}  // namespace mvkp
