#include "mvkp/track/follower.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

namespace {

// Fraction of the quadrilateral's area inside the frame.
double InsideFraction(const std::array<cv::Point2f, 4>& q, cv::Size frame) {
  std::vector<cv::Point2f> quad(q.begin(), q.end()), inter;
  const std::vector<cv::Point2f> rect = {{0, 0}, {float(frame.width), 0}, {float(frame.width), float(frame.height)},
                                         {0, float(frame.height)}};
  const double area = std::abs(cv::contourArea(quad));
  if (!(area > 0)) return 0;
  if (cv::contourArea(quad, true) < 0) std::reverse(quad.begin(), quad.end());
  return double(cv::intersectConvexConvex(quad, rect, inter, true)) / area;
}

}  // namespace

const char* FrameModeName(FrameMode m) {
  switch (m) {
    case FrameMode::kFocus: return "focus";
    case FrameMode::kTrack: return "track";
    case FrameMode::kFull: break;
  }
  return "full";
}

void FollowerOptions::Check() const {
  Require(lose_after >= 1, ErrorCode::kInvalidArgument, "lose-after must be >= 1");
  Require(weak_inliers >= 0, ErrorCode::kInvalidArgument, "weak-inliers must be >= 0");
  Require(agree_px >= 0, ErrorCode::kInvalidArgument, "agreement distance must be >= 0");
  tracker.Check();
}

VideoFollower::VideoFollower(const Recognizer& recognizer, const FollowerOptions& options)
    : rec_(&recognizer), options_(options), tracker_((options.Check(), options.tracker)) {}

void VideoFollower::SetObjectSize(const std::string& id, cv::Size size) {
  Require(size.width > 0 && size.height > 0, ErrorCode::kInvalidArgument, "target '" + id + "': bad object size");
  sizes_[id] = size;
}

void VideoFollower::Reset() {
  focus_.clear();
  tracked_id_.clear();
  misses_ = 0;
  tracker_.Stop();
}

cv::Size VideoFollower::ObjectSize(const Recognition& r) const {
  const auto it = sizes_.find(r.id);
  if (it != sizes_.end()) return it->second;
  // outline[2] is H * (w-1, h-1).
  const cv::Vec3d c = r.homography.inv() * cv::Vec3d(r.outline[2].x, r.outline[2].y, 1.0);
  return {int(std::lround(c[0] / c[2])) + 1, int(std::lround(c[1] / c[2])) + 1};
}

Recognition VideoFollower::Tracked() const {
  Recognition t;
  t.id = tracked_id_;
  t.homography = tracker_.homography();
  t.outline = tracker_.outline();
  t.inliers = tracker_.inliers();
  return t;
}

FollowedFrame VideoFollower::Process(const cv::Mat& gray) {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "video follower: frame must be 8-bit, one channel");
  Timer timer;
  FollowedFrame out;
  bool tracking = options_.track && tracker_.active();
  if (tracking && !tracker_.DueForRedetect()) {
    if (tracker_.Update(gray)) {
      out.mode = FrameMode::kTrack;
      out.found = {Tracked()};
      out.tracked = true;
      misses_ = 0;
      out.ms = timer.ElapsedMs();
      return out;
    }
    tracking = false;  // failed: the recogniser looks for it in this frame
  }
  bool tracked_ok = tracking && tracker_.Update(gray);  // a redetect frame: both
  const bool focused = options_.focus && !focus_.empty();
  out.mode = focused ? FrameMode::kFocus : FrameMode::kFull;
  out.recognition = focused ? rec_->RecognizeOne(gray, focus_) : rec_->Recognize(gray);
  const RecognitionResult& r = out.recognition;
  if (!r.found.empty()) {
    out.found = r.found;
    focus_ = r.found.front().id;
    misses_ = 0;
    if (options_.track) {
      const Recognition& d = r.found.front();
      const cv::Size size = ObjectSize(d);
      if (tracked_ok && d.id == tracked_id_ && tracker_.object_size() == size &&
          MeanCornerError(tracker_.homography(), d.homography, size) <= options_.agree_px) {
        tracker_.Confirm();
        Recognition& f = out.found.front();
        f.homography = tracker_.homography();
        f.outline = tracker_.outline();
        out.tracked = true;
      } else {
        tracked_id_ = d.id;
        if (!tracker_.Start(gray, d.homography, size)) {
          tracker_.Stop();
        } else if (d.inliers < options_.weak_inliers || InsideFraction(d.outline, gray.size()) < 0.5) {
          tracker_.RequestRedetect();
        }
      }
    }
  } else if (tracked_ok) {
    out.found = {Tracked()};
    out.tracked = true;
    misses_ = 0;
  } else {
    tracker_.Stop();
    if (focused && ++misses_ >= options_.lose_after) {
      focus_.clear();
      misses_ = 0;
    }
  }
  out.ms = timer.ElapsedMs();
  return out;
}

}  // namespace mvkp
