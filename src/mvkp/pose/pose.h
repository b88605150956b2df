// 3-D pose of a recognised planar target relative to a calibrated camera
// (thesis §6.2): from the homography object pixels -> frame pixels, the
// camera intrinsics and the target's physical width.
//
// Target coordinates: the plane z = 0, origin at the CENTRE of the target, x
// to the right and y down along the target image, z = x × y pointing into the
// target (away from a camera that faces it), in the units of physical_width
// (metres in the CLI). Object pixel (u, v) — pixel centres at integers, as in
// Recognition::outline — sits at ((u - (w-1)/2) s, (v - (h-1)/2) s, 0) with
// s = physical_width / w, so the image's full extent is physical_width wide.
//
// The camera frame is OpenCV's: x right, y down, z forward; tvec is the target
// centre in it, and R (rvec) turns target coordinates into camera coordinates:
// X_cam = R X_target + tvec.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace mvkp {

struct CameraModel {
  cv::Matx33d K = cv::Matx33d::eye();  // fx 0 cx; 0 fy cy; 0 0 1, pixels
  cv::Mat dist;                        // 1xN CV_64F, N in {4, 5, 8, 12, 14}; empty: no distortion
  cv::Size image_size;                 // frame size K was calibrated for; 0x0 if the file does not say
};

// Reads an OpenCV FileStorage file (YAML, XML or JSON) as written by OpenCV's
// calibration sample: camera_matrix (3x3), distortion_coefficients (optional),
// image_width and image_height (optional, both or neither). cameraMatrix and
// distCoeffs are accepted as aliases. Throws Error(kIo) for a missing or
// unreadable file and Error(kInvalidArgument) for a file that is not
// FileStorage, a missing or ill-shaped matrix, non-finite values,
// non-positive focal lengths or image size; messages name the file.
CameraModel LoadCamera(const std::string& path);

// The intrinsics for frames of `frame` size: K scaled per axis when the frame
// is a resized calibration frame (cv::resize convention: pixel centres map as
// (x + 0.5) * scale - 0.5); distortion coefficients are scale-free. Returns
// cam unchanged when the sizes agree or cam.image_size is unknown. Throws
// Error(kInvalidArgument) when the aspect ratios differ by more than 1 %
// (a crop, not a resize: the intrinsics cannot be derived).
CameraModel ScaledTo(const CameraModel& cam, cv::Size frame);

struct PoseOptions {
  int grid = 3;                       // grid x grid target points (corners included) projected through H
  bool refine = true;                 // Levenberg–Marquardt refinement of the IPPE solutions
  double max_reprojection_px = 10.0;  // RMS distance between H's and the pose's projections; above: not a pose
  void Check() const;                 // throws Error(kInvalidArgument)
};

struct Pose {
  cv::Vec3d rvec, tvec;                 // Rodrigues vector; target centre in camera coordinates
  cv::Matx33d R = cv::Matx33d::eye();   // rotation of rvec
  double distance = 0;                  // |tvec|: camera centre to target centre
  double reprojection_px = 0;           // RMS over the grid points, pixels
  bool ok = false;                      // false: no physically plausible pose (fields then undefined)
};

// Pose of the target whose homography (object pixels -> frame pixels) is
// H_object_to_frame, for an object image of object_width_px x
// object_height_px pixels that is physical_width wide. The grid points are
// mapped through H (frame pixels, distorted as the frame is) and solved with
// IPPE (both planar solutions), each refined; the plausible one with the
// smaller error wins. Not ok when H is degenerate or maps a grid point to
// infinity, when the target would be behind the camera or seen from behind
// (a mirrored H), or when the error exceeds max_reprojection_px — H then
// cannot come from a plane seen by this camera (wrong intrinsics or a bad
// match). cam must already suit the frame (ScaledTo). Throws
// Error(kInvalidArgument) for non-positive sizes or width.
Pose EstimatePose(const cv::Matx33d& H_object_to_frame, int object_width_px, int object_height_px,
                  double physical_width, const CameraModel& cam, const PoseOptions& options = {});

}  // namespace mvkp
