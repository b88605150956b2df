// Following recognised targets through a video: the per-frame policy of
// `mvkp video` and bench/video_track.cc, so both measure the same thing.
//
// Every target in view is followed, each on its own (issue 20): a target
// found by a full search (Recognizer::Recognize) joins the followed ones (at
// most max_targets), and leaves them after lose_after consecutive frames in
// which it was looked for and not found. While targets are followed, the full
// search runs every search_every frames to find new ones (and on every frame
// while none is followed); a followed target is checked by a focused search
// of its own (Recognizer::RecognizeOne, the thesis's temporal focus, §6.3.1:
// its own Matcher, more sensitive and on hard frames more accurate than the
// full search).
//
// Without tracking (FollowerOptions::track = false) every followed target is
// looked for in every frame (focused), plus the periodic full search; without
// focus every frame is a full search.
//
// With tracking, each followed target has its own TargetTracker, started
// from its detection, and frames in which no check is due are answered by
// the trackers alone (mode kTrack). A target is checked by the recogniser
// every tracker.redetect_every frames, or as soon as its tracking fails. On
// such a frame:
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
// Without focus the checks are full searches.
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
  int lose_after = 3;     // consecutive misses of a followed target before it is no longer followed
  int search_every = 10;  // while targets are followed: frames between full searches for new ones (1: every frame)
  int max_targets = 20;   // targets followed at once (ARCore tracks up to 20 images); more are reported, not followed
  bool track = true;      // optical-flow tracking between detections
  int weak_inliers = 30;  // detections with fewer inliers are re-checked on the next frame
  double agree_px = 2.0;  // detection within this mean corner distance of the tracker: keep the tracker's pose
  TrackerOptions tracker;
  void Check() const;     // throws Error(kInvalidArgument)
};

struct FollowedFrame {
  // The costliest search that ran: kFull (the full search, perhaps with
  // focused ones), kFocus (focused searches only), kTrack (trackers alone).
  FrameMode mode = FrameMode::kFull;
  // Every target in the frame, most inliers first. A pose from a tracker
  // (by_tracker[k]) has the tracker's homography inliers; votes and score
  // are 0 unless the recogniser also found it.
  std::vector<Recognition> found;
  std::vector<bool> by_tracker;   // one per found
  bool tracked = false;           // any pose in found is a tracker's
  // The recogniser's results of this frame, merged: the full search's and
  // the focused searches' found (a focused answer replacing the full
  // search's for its target) and summed timings (empty in kTrack frames).
  RecognitionResult recognition;
  double ms = 0;                  // wall clock of Process: recogniser and trackers
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

  void Reset();  // forget the followed targets and their trackers (e.g. on a cut)
  std::vector<std::string> followed() const;  // in the order they were first found
  const FollowerOptions& options() const { return options_; }

 private:
  struct Target {
    std::string id;
    TargetTracker tracker;
    int misses = 0;  // consecutive frames looked for and not found
  };
  cv::Size ObjectSize(const Recognition& r) const;
  // Starts (or restarts) t's tracker from detection d.
  void StartTracker(Target& t, const cv::Mat& gray, const Recognition& d);

  const Recognizer* rec_;
  FollowerOptions options_;
  std::map<std::string, cv::Size> sizes_;
  std::vector<Target> targets_;
  int since_full_ = 0;  // frames since the last full search
};

}  // namespace mvkp
