// Following recognised targets through a video: the per-frame policy of
// `mvkp video` and bench/video_track.cc, so both measure the same thing.
//
// Without tracking (FollowerOptions::track = false) it is the thesis's
// temporal focus (§6.3.1): after a detection the next frames look for that
// target alone (Recognizer::RecognizeOne) and return to the full search after
// lose_after consecutive misses; without focus every frame is a full search.
//
// With tracking, a detection starts a TargetTracker on the first target found
// and the following frames are answered by the tracker alone (mode kTrack).
// Every tracker.redetect_every frames, or as soon as tracking fails, the
// recogniser runs again (focused on the tracked id). On such a frame:
//   * detection and tracker agree (mean corner distance <= agree_px): the
//     tracker's pose is kept (steadier) and the frame becomes its new
//     reference (TargetTracker::Confirm);
//   * they disagree, or tracking failed: the tracker restarts from the
//     detection (drift corrected); a start from a weak detection (fewer than
//     weak_inliers inliers, or less than half the outline inside the frame)
//     is checked again on the very next frame, since the tracker would carry
//     its pose error until the next check;
//   * no detection but the tracker holds: the tracker's pose is reported and
//     the recogniser tries again on the next frame.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/recognize/recognizer.h"
#include "mvkp/track/tracker.h"

namespace mvkp {

enum class FrameMode { kFull, kFocus, kTrack };
const char* FrameModeName(FrameMode m);  // "full" | "focus" | "track"

struct FollowerOptions {
  bool focus = true;      // temporal focus; false: the recogniser always searches all targets
  int lose_after = 3;     // consecutive misses of the focused target before the full search
  bool track = true;      // optical-flow tracking between detections
  int weak_inliers = 30;  // detections with fewer inliers are re-checked on the next frame
  double agree_px = 2.0;  // detection within this mean corner distance of the tracker: keep the tracker's pose
  TrackerOptions tracker;
  void Check() const;     // throws Error(kInvalidArgument)
};

struct FollowedFrame {
  FrameMode mode = FrameMode::kFull;  // the search that ran; kTrack: the tracker alone
  // Targets in the frame, as RecognitionResult::found. When `tracked`, the
  // first is the tracker's (inliers: its homography inliers; votes, score 0
  // unless the recogniser also found it).
  std::vector<Recognition> found;
  bool tracked = false;
  RecognitionResult recognition;  // the recogniser's own result (empty in kTrack frames)
  double ms = 0;                  // wall clock of Process: recogniser and tracker
};

class VideoFollower {
 public:
  // `recognizer` must outlive the follower.
  explicit VideoFollower(const Recognizer& recognizer, const FollowerOptions& options = {});

  // Object-image size of a target (its model's object_width/height), needed
  // to track it; without it the size is recovered from the detection's
  // outline and homography.
  void SetObjectSize(const std::string& id, cv::Size size);

  // One 8-bit grayscale frame (Error(kInvalidArgument) otherwise).
  FollowedFrame Process(const cv::Mat& gray);

  void Reset();  // forget focus and track (e.g. on a cut)
  const std::string& focus() const { return focus_; }
  const TargetTracker& tracker() const { return tracker_; }
  const FollowerOptions& options() const { return options_; }

 private:
  cv::Size ObjectSize(const Recognition& r) const;
  Recognition Tracked() const;

  const Recognizer* rec_;
  FollowerOptions options_;
  TargetTracker tracker_;
  std::map<std::string, cv::Size> sizes_;
  std::string focus_, tracked_id_;
  int misses_ = 0;
};

}  // namespace mvkp
