#include "mvkp/track/follower.h"

#include <algorithm>
#include <cmath>
#include <optional>

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
  Require(search_every >= 1, ErrorCode::kInvalidArgument, "search-every must be >= 1");
  Require(max_targets >= 1, ErrorCode::kInvalidArgument, "max-targets must be >= 1");
  Require(weak_inliers >= 0, ErrorCode::kInvalidArgument, "weak-inliers must be >= 0");
  Require(agree_px >= 0, ErrorCode::kInvalidArgument, "agreement distance must be >= 0");
  tracker.Check();
}

VideoFollower::VideoFollower(const Recognizer& recognizer, const FollowerOptions& options)
    : rec_(&recognizer), options_((options.Check(), options)) {}

void VideoFollower::SetObjectSize(const std::string& id, cv::Size size) {
  Require(size.width > 0 && size.height > 0, ErrorCode::kInvalidArgument, "target '" + id + "': bad object size");
  sizes_[id] = size;
}

void VideoFollower::Reset() {
  targets_.clear();
  since_full_ = 0;
}

std::vector<std::string> VideoFollower::followed() const {
  std::vector<std::string> ids;
  for (const auto& t : targets_) ids.push_back(t.id);
  return ids;
}

cv::Size VideoFollower::ObjectSize(const Recognition& r) const {
  const auto it = sizes_.find(r.id);
  if (it != sizes_.end()) return it->second;
  // outline[2] is H * (w-1, h-1).
  const cv::Vec3d c = r.homography.inv() * cv::Vec3d(r.outline[2].x, r.outline[2].y, 1.0);
  return {int(std::lround(c[0] / c[2])) + 1, int(std::lround(c[1] / c[2])) + 1};
}

void VideoFollower::StartTracker(Target& t, const cv::Mat& gray, const Recognition& d) {
  if (!t.tracker.Start(gray, d.homography, ObjectSize(d))) {
    t.tracker.Stop();
  } else if (d.inliers < options_.weak_inliers || InsideFraction(d.outline, gray.size()) < 0.5) {
    t.tracker.RequestRedetect();
  }
}

FollowedFrame VideoFollower::Process(const cv::Mat& gray) {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "video follower: frame must be 8-bit, one channel");
  Timer timer;
  FollowedFrame out;
  const std::size_t n = targets_.size();
  // 1. The trackers; a target whose check is due, or whose tracking failed,
  // or that is not tracked, needs the recogniser.
  std::vector<char> tracked_ok(n, 0), check(n, 0);
  bool any_check = false;
  for (std::size_t i = 0; i < n; ++i) {
    TargetTracker& tr = targets_[i].tracker;
    if (options_.track && tr.active()) {
      const bool due = tr.DueForRedetect();
      tracked_ok[i] = tr.Update(gray);  // on a check frame: both
      check[i] = due || !tracked_ok[i];
    } else {
      check[i] = 1;
    }
    any_check = any_check || check[i];
  }
  ++since_full_;
  const bool full = n == 0 || since_full_ >= options_.search_every || (!options_.focus && any_check);
  out.mode = FrameMode::kTrack;

  // 2. The recogniser: the full search (for new targets; without focus also
  // the check of the followed ones), then a focused search for each target
  // to check.
  std::vector<std::optional<Recognition>> det(n);
  std::vector<Recognition> fresh;  // found by the full search, not followed yet
  RecognitionResult& rr = out.recognition;
  if (full) {
    out.mode = FrameMode::kFull;
    since_full_ = 0;
    // One more candidate verified per followed target: they have the most
    // votes, and would otherwise take the places of new ones.
    rr = rec_->Recognize(gray, std::min(100000, rec_->options().max_candidates + int(n)));
    for (const Recognition& d : rr.found) {
      const auto it = std::find_if(targets_.begin(), targets_.end(), [&](const Target& t) { return t.id == d.id; });
      // With focus a followed target is checked by its own focused search
      // (its own Matcher: on the 300-frame clips of bench/video_track.cc
      // the full search's pose was once 15 px off where the focused one was
      // right); the full search is for new targets.
      if (it == targets_.end()) fresh.push_back(d);
      else if (!options_.focus) det[std::size_t(it - targets_.begin())] = d;
    }
  }
  if (options_.focus) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!check[i] || det[i]) continue;
      const RecognitionResult one = rec_->RecognizeOne(gray, targets_[i].id);
      if (!full) out.mode = FrameMode::kFocus;
      rr.keypoints += one.keypoints;
      rr.matches += one.matches;
      rr.candidates += one.candidates;
      rr.detect_ms += one.detect_ms;
      rr.describe_ms += one.describe_ms;
      rr.search_ms += one.search_ms;
      rr.verify_ms += one.verify_ms;
      // The focused answer replaces the full search's for this target.
      rr.found.erase(std::remove_if(rr.found.begin(), rr.found.end(),
                                    [&](const Recognition& x) { return x.id == targets_[i].id; }),
                     rr.found.end());
      rr.found.insert(rr.found.end(), one.found.begin(), one.found.end());
      if (!one.found.empty()) det[i] = one.found.front();
    }
  }

  // 3. Each followed target: its detection, else its tracker, else a miss.
  std::vector<std::pair<Recognition, bool>> found;  // (target, pose by tracker)
  for (std::size_t i = 0; i < n; ++i) {
    Target& t = targets_[i];
    if (det[i]) {
      Recognition d = *det[i];
      t.misses = 0;
      bool by_tracker = false;
      if (options_.track) {
        const cv::Size size = ObjectSize(d);
        if (tracked_ok[i] && t.tracker.object_size() == size &&
            MeanCornerError(t.tracker.homography(), d.homography, size) <= options_.agree_px) {
          t.tracker.Confirm();
          d.homography = t.tracker.homography();
          d.outline = t.tracker.outline();
          by_tracker = true;
        } else {
          StartTracker(t, gray, d);
        }
      }
      found.emplace_back(d, by_tracker);
    } else if (tracked_ok[i]) {
      Recognition x;
      x.id = t.id;
      x.homography = t.tracker.homography();
      x.outline = t.tracker.outline();
      x.inliers = t.tracker.inliers();
      found.emplace_back(x, true);
      t.misses = 0;
    } else {
      t.tracker.Stop();
      ++t.misses;
    }
  }
  targets_.erase(std::remove_if(targets_.begin(), targets_.end(),
                                [&](const Target& t) { return t.misses >= options_.lose_after; }),
                 targets_.end());

  // 4. New targets: followed from now on (up to max_targets), reported anyway.
  for (const Recognition& d : fresh) {
    if (int(targets_.size()) < options_.max_targets) {
      targets_.push_back({d.id, TargetTracker(options_.tracker), 0});
      if (options_.track) StartTracker(targets_.back(), gray, d);
    }
    found.emplace_back(d, false);
  }

  std::stable_sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first.inliers > b.first.inliers; });
  for (auto& [x, by_tracker] : found) {
    out.found.push_back(std::move(x));
    out.by_tracker.push_back(by_tracker);
    out.tracked = out.tracked || by_tracker;
  }
  out.ms = timer.ElapsedMs();
  return out;
}

}  // namespace mvkp
