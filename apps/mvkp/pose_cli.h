// --camera / --width-m of `mvkp recognize` and `mvkp video` (thesis §6.2):
// the camera intrinsics, each target's object size and physical width, and the
// 3-D pose of each found target (mvkp/pose/pose.h).
#pragma once

#include <map>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mvkp/pose/pose.h"
#include "mvkp/recognize/recognizer.h"

namespace mvkp::cli {

class PoseSupport {
 public:
  // Adds --camera and --width-m to a command.
  void AddOptions(CLI::App* cmd);
  // Loads the --camera file (one-line errors naming it); --width-m without
  // --camera is an error. Call before reading the database or any frame.
  void Load();
  bool enabled() const { return enabled_; }

  // Records a target: the object size of its model and its width in metres,
  // the "width_m" of its metadata JSON (a positive number, else an error
  // naming the target) or else --width-m; without either it gets no pose.
  void AddTarget(const std::string& id, const std::string& meta_json, int object_width, int object_height,
                 const std::string& db);

  // The camera for frames of this size (ScaledTo; `what` names the frame in
  // the error when the aspect ratio differs from the calibration's).
  const CameraModel& Camera(cv::Size frame, const std::string& what);
  // The pose of a found target in a frame of this size; none without pose
  // support, without a width, or when EstimatePose finds no plausible pose.
  std::optional<Pose> Estimate(const Recognition& found, cv::Size frame, const std::string& what);

  // {"rvec", "tvec" (metres, camera frame), "R", "distance_m", "reprojection_px"}.
  static nlohmann::json Json(const Pose& p);
  // Axes at the target centre, half the target's width long (x red, y green, z blue, into the target).
  void DrawAxes(cv::Mat& bgr, const std::string& id, const Pose& p, cv::Size frame, const std::string& what);

 private:
  struct Target {
    int width = 0, height = 0;  // object pixels
    double width_m = 0;         // 0: unknown
  };
  std::string camera_path_;
  double default_width_m_ = 0;           // 0: none
  const CLI::Option* width_option_ = nullptr;
  bool enabled_ = false;
  CameraModel camera_;
  cv::Size scaled_for_;  // frame size camera_scaled_ suits
  CameraModel camera_scaled_;
  std::map<std::string, Target> targets_;
};

}  // namespace mvkp::cli
