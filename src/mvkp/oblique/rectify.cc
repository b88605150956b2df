#include "mvkp/oblique/rectify.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

void RectifyOptions::Check() const {
  Require(scale > 0.01 && scale <= 16 && max_ray_deg > 0 && max_ray_deg < 89 && max_side >= 64 && max_side <= 16384, ErrorCode::kInvalidArgument,
          "RectifyOptions: scale in (0.01, 16], max_ray_deg in (0, 89), max_side in [64, 16384]");
}

Rectification RectifyForTilt(cv::Size size, const cv::Matx33d& K, double tilt_deg, const RectifyOptions& o) {
  o.Check();
  Require(size.width > 0 && size.height > 0 && tilt_deg >= 0 && tilt_deg < 89, ErrorCode::kInvalidArgument,
          "RectifyForTilt: an empty view, or a tilt outside [0, 89) degrees");
  Require(std::abs(cv::determinant(K)) > 1e-12, ErrorCode::kInvalidArgument, "RectifyForTilt: singular K");
  const cv::Matx33d Ki = K.inv();
  Rectification r;
  r.tilt_deg = tilt_deg;
  const double t = tilt_deg * CV_PI / 180;
  r.down = {0, std::sin(t), std::cos(t)};
  // the rotation taking down to the optical axis
  const cv::Vec3d z(0, 0, 1), axis = r.down.cross(z);
  const double s = cv::norm(axis), c = r.down.dot(z);
  cv::Matx33d R = cv::Matx33d::eye();
  if (s > 1e-12) cv::Rodrigues(cv::Vec3d(axis * (std::atan2(s, c) / s)), R);
  const cv::Matx33d H0 = K * R * Ki;
  // bounds of the view's rays within max_ray_deg of down
  const double cos_ray = std::cos(o.max_ray_deg * CV_PI / 180);
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  const int g = 48;
  for (int iy = 0; iy <= g; ++iy)
    for (int ix = 0; ix <= g; ++ix) {
      const cv::Vec3d p((size.width - 1) * double(ix) / g, (size.height - 1) * double(iy) / g, 1);
      cv::Vec3d ray = Ki * p;
      ray /= cv::norm(ray);
      if (ray.dot(r.down) < cos_ray) continue;
      const cv::Vec3d q = H0 * p;
      if (!(q[2] > 1e-12)) continue;
      x0 = std::min(x0, q[0] / q[2]), x1 = std::max(x1, q[0] / q[2]);
      y0 = std::min(y0, q[1] / q[2]), y1 = std::max(y1, q[1] / q[2]);
    }
  if (!(x1 > x0 && y1 > y0)) {  // no ray near enough to down: nothing to rectify
    r.H = cv::Matx33d::eye();
    r.size = size;
    return r;
  }
  const double k = std::min(o.scale, o.max_side / std::max(x1 - x0, y1 - y0));
  const cv::Matx33d S(k, 0, -k * x0, 0, k, -k * y0, 0, 0, 1);
  r.H = S * H0;
  r.size = cv::Size(std::max(1, int(std::ceil(k * (x1 - x0)))), std::max(1, int(std::ceil(k * (y1 - y0)))));
  return r;
}

cv::Mat Rectify(const cv::Mat& view, const Rectification& r) {
  Require(!view.empty() && r.size.width > 0 && r.size.height > 0, ErrorCode::kInvalidArgument,
          "Rectify: empty view or rectification");
  cv::Mat out;
  cv::warpPerspective(view, out, cv::Mat(r.H), r.size, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return out;
}

}  // namespace mvkp
