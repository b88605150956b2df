#include "mvkp/pose/pose.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

bool AllFinite(const cv::Mat& m) { return cv::checkRange(m, true, nullptr, -1e300, 1e300); }

// The first of the names present in fs, or an empty node.
cv::FileNode Find(const cv::FileStorage& fs, std::initializer_list<const char*> names) {
  for (const char* n : names) {
    cv::FileNode node = fs[n];
    if (!node.empty() && !node.isNone()) return node;
  }
  return {};
}

// Reads a matrix node; empty Mat when the node is not one (a number, a string, a map of other keys).
cv::Mat ReadMatrix(const cv::FileNode& node) {
  cv::Mat m;
  if (node.isMap()) {
    node >> m;  // an opencv-matrix
  } else if (node.isSeq()) {
    // A plain sequence of numbers (JSON / hand-written YAML) instead of an opencv-matrix.
    std::vector<double> v;
    for (const auto& e : node) {
      if (!e.isReal() && !e.isInt()) return {};
      v.push_back(double(e));
    }
    m = cv::Mat(v, true).reshape(1, 1);
  }
  if (!m.empty()) m.convertTo(m, CV_64F);
  return m;
}

}  // namespace

CameraModel LoadCamera(const std::string& path) {
  std::error_code ec;
  Require(std::filesystem::exists(path, ec), ErrorCode::kIo, path + ": no such camera file");
  Require(std::filesystem::is_regular_file(path, ec), ErrorCode::kIo, path + ": not a file");
  Require(std::ifstream(path).good(), ErrorCode::kIo, path + ": cannot read the camera file");
  const std::string bad = path + ": not an OpenCV calibration file (YAML/XML/JSON FileStorage): ";
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception&) {
    // The parser's own message spans several lines and names OpenCV internals.
    throw Error(ErrorCode::kInvalidArgument, bad + "cannot be parsed");
  }
  Require(fs.isOpened(), ErrorCode::kInvalidArgument, bad + "cannot be parsed");

  CameraModel cam;
  try {
    const cv::FileNode kn = Find(fs, {"camera_matrix", "cameraMatrix"});
    Require(!kn.empty(), ErrorCode::kInvalidArgument, path + ": no camera_matrix (nor cameraMatrix) in the file");
    const cv::Mat k = ReadMatrix(kn);
    Require(k.rows == 3 && k.cols == 3, ErrorCode::kInvalidArgument,
            path + ": camera_matrix must be a 3x3 matrix");
    Require(AllFinite(k), ErrorCode::kInvalidArgument, path + ": camera_matrix has non-finite values");
    cam.K = cv::Matx33d(k.ptr<double>());
    Require(cam.K(2, 0) == 0 && cam.K(2, 1) == 0 && cam.K(2, 2) == 1, ErrorCode::kInvalidArgument,
            path + ": camera_matrix's last row must be 0 0 1");
    Require(cam.K(0, 0) > 0 && cam.K(1, 1) > 0, ErrorCode::kInvalidArgument,
            path + ": camera_matrix focal lengths must be positive");

    const cv::FileNode dn = Find(fs, {"distortion_coefficients", "distCoeffs"});
    if (!dn.empty()) {
      cv::Mat d = ReadMatrix(dn);
      const int n = int(d.total());
      Require(!d.empty() && (d.rows == 1 || d.cols == 1) && (n == 4 || n == 5 || n == 8 || n == 12 || n == 14),
              ErrorCode::kInvalidArgument, path + ": distortion_coefficients must be a vector of 4, 5, 8, 12 or 14");
      Require(AllFinite(d), ErrorCode::kInvalidArgument, path + ": distortion_coefficients has non-finite values");
      cam.dist = d.reshape(1, 1).clone();
    }

    const cv::FileNode wn = fs["image_width"], hn = fs["image_height"];
    Require(wn.empty() == hn.empty(), ErrorCode::kInvalidArgument,
            path + ": image_width and image_height go together");
    if (!wn.empty()) {
      Require(wn.isInt() && hn.isInt() && int(wn) > 0 && int(hn) > 0, ErrorCode::kInvalidArgument,
              path + ": image_width and image_height must be positive integers");
      cam.image_size = cv::Size(int(wn), int(hn));
    }
  } catch (const cv::Exception&) {
    throw Error(ErrorCode::kInvalidArgument, bad + "unexpected content");
  }
  return cam;
}

CameraModel ScaledTo(const CameraModel& cam, cv::Size frame) {
  Require(frame.width > 0 && frame.height > 0, ErrorCode::kInvalidArgument, "ScaledTo: empty frame size");
  if (cam.image_size.width <= 0 || cam.image_size.height <= 0 || cam.image_size == frame) return cam;
  const double sx = double(frame.width) / cam.image_size.width, sy = double(frame.height) / cam.image_size.height;
  Require(std::abs(sx - sy) <= 0.01 * std::max(sx, sy), ErrorCode::kInvalidArgument,
          "the camera was calibrated for " + std::to_string(cam.image_size.width) + "x" +
              std::to_string(cam.image_size.height) + " frames; a " + std::to_string(frame.width) + "x" +
              std::to_string(frame.height) + " frame has another aspect ratio");
  CameraModel out = cam;
  out.K(0, 0) *= sx;
  out.K(1, 1) *= sy;
  out.K(0, 1) *= sx;  // skew, in x pixels per unit of normalised y
  out.K(0, 2) = (cam.K(0, 2) + 0.5) * sx - 0.5;
  out.K(1, 2) = (cam.K(1, 2) + 0.5) * sy - 0.5;
  out.image_size = frame;
  return out;
}

void PoseOptions::Check() const {
  Require(grid >= 2 && grid <= 50, ErrorCode::kInvalidArgument, "pose grid must be in [2, 50]");
  Require(max_reprojection_px > 0, ErrorCode::kInvalidArgument, "pose max_reprojection_px must be > 0");
}

Pose EstimatePose(const cv::Matx33d& H, int object_width_px, int object_height_px, double physical_width,
                  const CameraModel& cam, const PoseOptions& options) {
  options.Check();
  Require(object_width_px > 0 && object_height_px > 0, ErrorCode::kInvalidArgument,
          "pose: the object size must be positive");
  Require(std::isfinite(physical_width) && physical_width > 0, ErrorCode::kInvalidArgument,
          "pose: the physical width must be positive");
  Pose none;
  for (int i = 0; i < 9; ++i)
    if (!std::isfinite(H.val[i])) return none;

  const int g = options.grid;
  const double s = physical_width / object_width_px;
  const double cu = (object_width_px - 1) / 2.0, cv_ = (object_height_px - 1) / 2.0;
  // H and -H are the same homography; fix the sign so the target centre has w > 0.
  const cv::Matx33d Hs = (H * cv::Vec3d(cu, cv_, 1))[2] < 0 ? cv::Matx33d(-H) : H;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (int j = 0; j < g; ++j)
    for (int i = 0; i < g; ++i) {
      const double u = (object_width_px - 1) * double(i) / (g - 1), v = (object_height_px - 1) * double(j) / (g - 1);
      const cv::Vec3d p = Hs * cv::Vec3d(u, v, 1);
      // A point on or beyond the horizon of H (the sign of w changes across the target): no camera sees it all.
      if (!(p[2] > 1e-12 * (std::abs(p[0]) + std::abs(p[1]) + 1))) return none;
      object.emplace_back((u - cu) * s, (v - cv_) * s, 0.0);
      image.emplace_back(p[0] / p[2], p[1] / p[2]);
    }
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    cv::solvePnPGeneric(object, image, cv::Mat(cam.K), cam.dist, rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
  } catch (const cv::Exception&) {
    return none;  // degenerate H (collinear grid points)
  }

  Pose best;
  for (std::size_t k = 0; k < rvecs.size(); ++k) {
    cv::Mat rvec = rvecs[k].clone(), tvec = tvecs[k].clone();
    rvec.convertTo(rvec, CV_64F);
    tvec.convertTo(tvec, CV_64F);
    if (options.refine) {
      try {
        cv::solvePnPRefineLM(object, image, cv::Mat(cam.K), cam.dist, rvec, tvec);
      } catch (const cv::Exception&) {
      }
    }
    if (!AllFinite(rvec) || !AllFinite(tvec)) continue;
    Pose p;
    p.rvec = cv::Vec3d(rvec.ptr<double>());
    p.tvec = cv::Vec3d(tvec.ptr<double>());
    cv::Rodrigues(p.rvec, p.R);
    // Every grid point in front of the camera ...
    bool front = true;
    for (const auto& X : object) front = front && (p.R * cv::Vec3d(X.x, X.y, X.z) + p.tvec)[2] > 0;
    // ... and the camera on the printed side (-z) of the target: a mirrored H gives a pose seen from behind.
    const cv::Vec3d normal(p.R(0, 2), p.R(1, 2), p.R(2, 2));
    if (!front || normal.dot(p.tvec) <= 0) continue;
    std::vector<cv::Point2d> reproj;
    cv::projectPoints(object, p.rvec, p.tvec, cv::Mat(cam.K), cam.dist, reproj);
    double sum = 0;
    for (std::size_t i = 0; i < image.size(); ++i) {
      const cv::Point2d d = reproj[i] - image[i];
      sum += d.dot(d);
    }
    p.reprojection_px = std::sqrt(sum / image.size());
    p.distance = cv::norm(p.tvec);
    p.ok = std::isfinite(p.reprojection_px) && p.reprojection_px <= options.max_reprojection_px;
    if (p.ok && (!best.ok || p.reprojection_px < best.reprojection_px)) best = p;
  }
  return best;
}

}  // namespace mvkp
