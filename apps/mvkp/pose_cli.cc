#include "pose_cli.h"

#include <cmath>

#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"
#include "mvkp/serve/encode.h"

namespace mvkp::cli {

void PoseSupport::AddOptions(CLI::App* cmd) {
  cmd->add_option("--camera", camera_path_,
                  "camera intrinsics (OpenCV calibration YAML/XML/JSON: camera_matrix, distortion_coefficients, "
                  "image_width, image_height): adds each found target's 3-D pose");
  width_option_ = cmd->add_option("--width-m", default_width_m_,
                                  "physical width of the targets in metres, for targets whose metadata has no "
                                  "\"width_m\"");
}

void PoseSupport::Load() {
  if (width_option_ && width_option_->count()) {
    Require(std::isfinite(default_width_m_) && default_width_m_ > 0, ErrorCode::kInvalidArgument,
            "--width-m must be a positive number of metres");
    Require(!camera_path_.empty(), ErrorCode::kInvalidArgument, "--width-m needs --camera");
  }
  if (camera_path_.empty()) return;
  camera_ = LoadCamera(camera_path_);
  enabled_ = true;
}

void PoseSupport::AddTarget(const std::string& id, const std::string& meta_json, int object_width, int object_height,
                            const std::string& db) {
  if (!enabled_) return;
  Target t{object_width, object_height, default_width_m_};
  // The store validates the JSON object (rows written before its limits may
  // be deep or huge: those count as no metadata); only width_m is ours to check.
  nlohmann::json meta;
  TryParseJsonLimited(meta_json, meta, MetaJsonLimits());
  if (meta.is_object() && meta.contains("width_m")) {
    const nlohmann::json& w = meta["width_m"];
    Require(w.is_number() && std::isfinite(w.get<double>()) && w.get<double>() > 0, ErrorCode::kInvalidArgument,
            db + ": target '" + id + "': metadata width_m must be a positive number (metres), not " + w.dump());
    t.width_m = w.get<double>();
  }
  targets_[id] = t;
}

const CameraModel& PoseSupport::Camera(cv::Size frame, const std::string& what) {
  if (frame != scaled_for_) {
    try {
      camera_scaled_ = ScaledTo(camera_, frame);
    } catch (const Error& e) {
      throw Error(e.code(), what + ": " + camera_path_ + ": " + e.what());
    }
    scaled_for_ = frame;
  }
  return camera_scaled_;
}

std::optional<Pose> PoseSupport::Estimate(const Recognition& found, cv::Size frame, const std::string& what) {
  if (!enabled_) return std::nullopt;
  const auto it = targets_.find(found.id);
  if (it == targets_.end() || it->second.width_m <= 0) return std::nullopt;
  const Target& t = it->second;
  const Pose p = EstimatePose(found.homography, t.width, t.height, t.width_m, Camera(frame, what));
  if (!p.ok) return std::nullopt;
  return p;
}

nlohmann::json PoseSupport::Json(const Pose& p) { return serve::PoseJson(p); }

void PoseSupport::DrawAxes(cv::Mat& bgr, const std::string& id, const Pose& p, cv::Size frame,
                           const std::string& what) {
  const CameraModel& cam = Camera(frame, what);
  cv::drawFrameAxes(bgr, cv::Mat(cam.K), cam.dist, p.rvec, p.tvec, float(0.5 * targets_.at(id).width_m), 3);
}

}  // namespace mvkp::cli
