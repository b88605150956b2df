// Optical-flow tracking of a recognised planar target between detections
// (issue 6, video; the thesis had none).
//
// Start() takes a frame and the homography a detection found (object pixels ->
// frame pixels), seeds up to max_points Shi–Tomasi corners
// (cv::goodFeaturesToTrack) inside the target's projected outline and stores
// their object coordinates (through H^-1). Update() follows the points into
// the next frame with pyramidal Lucas–Kanade (cv::calcOpticalFlowPyrLK),
// drops those whose forward-backward error exceeds max_fb_error, and fits a
// homography object points -> tracked points robustly (FitGeometry, fixed RNG
// state: deterministic). Tracking fails (Update returns false and the tracker
// stops) when too few points or inliers remain, the outline is implausible
// (IsPlausibleOutline) or jumps/rescales absurdly within one frame, or the
// target no longer looks like it did at the last verified frame (normalised
// cross-correlation of the target region, warped back, below min_ncc: catches
// occlusion and cuts that the flow alone would follow onto the background).
// When fewer than reseed_below * max_points inliers remain, new corners are
// seeded inside the current outline.
//
// Cost on a 640x480 frame (one thread, 100 points): about 1-2 ms per Update;
// Start about 1-2 ms (corner detection over the target's box). Drift: object
// coordinates are fixed at seeding, but point positions are followed frame to
// frame, so errors accumulate (~1-2 px over 30 frames in the unit test);
// callers correct it by re-detecting (VideoFollower).
#pragma once

#include <array>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/match/matcher.h"

namespace mvkp {

struct TrackerOptions {
  int max_points = 100;             // corners seeded inside the target (200: no steadier, twice the LK time)
  double quality_level = 0.01;      // goodFeaturesToTrack: minimum corner quality, relative to the best
  double min_distance = 6;          // px between seeded corners
  int border = 3;                   // seed no closer than this to the outline (px): corners on the edge mix in background
  int pyramid_levels = 3;           // calcOpticalFlowPyrLK maxLevel (0: no pyramid)
  int window = 15;                  // LK window side (px, odd; 21 measured no better and slower)
  double max_fb_error = 1.0;        // forward-backward error (px) above which a point is dropped
  double ransac_threshold = 2.0;    // px, homography inliers
  RobustMethod robust = RobustMethod::kRansac;
  int min_points = 15;              // fewer homography inliers: tracking failed
  double min_inlier_fraction = 0.5; // of the points that survived the forward-backward check
  double reseed_below = 0.6;        // re-seed when fewer than this fraction of max_points remain
  double max_jump = 0.5;            // a corner moving more than this fraction of the outline diagonal in one frame: failure
  double max_area_change = 1.6;     // outline area changing by more than this factor in one frame: failure
  double min_ncc = 0.45;            // appearance check against the last verified frame (0: off)
  int redetect_every = 10;          // for callers (VideoFollower): frames between recogniser checks (0: only on failure)
  void Check() const;               // throws Error(kInvalidArgument)
};

class TargetTracker {
 public:
  explicit TargetTracker(const TrackerOptions& options = {});

  // Begins tracking the target of `object_size` (object pixels) that H puts
  // into `gray` (8-bit, one channel). Returns false (and does not track) if
  // fewer than min_points corners can be seeded inside the visible outline.
  // Throws Error(kInvalidArgument) for an empty or non-CV_8UC1 frame, a
  // non-positive object size, or a non-finite / implausible outline.
  bool Start(const cv::Mat& gray, const cv::Matx33d& H_object_to_frame, cv::Size object_size);

  // Follows the target into the next frame (same size and type as Start's).
  // True: *H_out (if given) is object pixels -> this frame. False: tracking
  // failed and the tracker stopped (call Start again). Throws
  // Error(kInvalidArgument) when not tracking (before Start or after a
  // failure), and for an empty frame, a wrong type or another size.
  bool Update(const cv::Mat& gray, cv::Matx33d* H_out = nullptr);

  // The last Update's frame and homography become the reference of the
  // appearance check and the count for redetect_every restarts (a recogniser
  // agreed with the tracker). No-op when not tracking.
  void Confirm();
  void Stop() { active_ = false; }
  // Makes DueForRedetect() true from the next Update on (a shaky start).
  void RequestRedetect() { since_verified_ = options_.redetect_every; }

  bool active() const { return active_; }
  const cv::Matx33d& homography() const { return H_; }            // valid while active
  std::array<cv::Point2f, 4> outline() const;                     // object corners in the last frame
  cv::Size object_size() const { return object_size_; }
  int points() const { return int(object_pts_.size()); }          // points being tracked
  int inliers() const { return inliers_; }                        // of the last Update
  double ncc() const { return ncc_; }                             // of the last Update's appearance check
  int frames_since_verified() const { return since_verified_; }   // Updates since Start / Confirm
  bool DueForRedetect() const {
    return options_.redetect_every > 0 && since_verified_ >= options_.redetect_every;
  }
  const TrackerOptions& options() const { return options_; }

 private:
  void CheckFrame(const cv::Mat& gray, const char* what) const;
  int Seed(const cv::Mat& gray, int wanted);
  void SetReference(const cv::Mat& gray, const cv::Matx33d& H);
  double Appearance(const cv::Mat& gray, const cv::Matx33d& H) const;

  TrackerOptions options_;
  bool active_ = false;
  cv::Size frame_size_, object_size_;
  cv::Matx33d H_ = cv::Matx33d::eye();
  std::vector<cv::Mat> prev_pyr_;
  cv::Mat prev_gray_;
  std::vector<cv::Point2f> object_pts_, frame_pts_;
  int inliers_ = 0;
  double ncc_ = 1;
  int since_verified_ = 0;
  // Appearance reference: the verified frame's target region at half resolution.
  cv::Mat ref_patch_, ref_mask_;
  cv::Matx33d ref_to_patch_ = cv::Matx33d::eye();  // reference-frame pixels -> patch pixels
  cv::Matx33d ref_H_ = cv::Matx33d::eye();         // object -> reference frame
};

}  // namespace mvkp
