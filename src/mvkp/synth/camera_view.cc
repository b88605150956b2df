#include "mvkp/synth/camera_view.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

constexpr double kDeg = CV_PI / 180.0;

cv::Matx33d RotZ(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return {c, -s, 0, s, c, 0, 0, 0, 1};
}
cv::Matx33d RotX(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return {1, 0, 0, 0, c, -s, 0, s, c};
}

// The smallest rotation taking (0, 0, 1) to the unit vector r (Rodrigues).
cv::Matx33d AlignZ(const cv::Vec3d& r) {
  const cv::Vec3d z(0, 0, 1);
  cv::Vec3d axis = z.cross(r);
  const double s = cv::norm(axis), c = z.dot(r);
  if (s < 1e-12) return cv::Matx33d::eye();
  axis /= s;
  const cv::Matx33d K(0, -axis[2], axis[1], axis[2], 0, -axis[0], -axis[1], axis[0], 0);
  return cv::Matx33d::eye() + s * K + (1 - c) * (K * K);
}

struct Camera {
  double f, cx, cy;
};

Camera MakeCamera(cv::Size frame, double hfov_deg) {
  return {0.5 * frame.width / std::tan(0.5 * hfov_deg * kDeg), 0.5 * (frame.width - 1), 0.5 * (frame.height - 1)};
}

cv::Matx33d PlaneHomography(const Camera& cam, const cv::Matx33d& R, const cv::Vec3d& T, cv::Size target) {
  const cv::Matx33d K(cam.f, 0, cam.cx, 0, cam.f, cam.cy, 0, 0, 1);
  const cv::Matx33d M(R(0, 0), R(0, 1), T[0], R(1, 0), R(1, 1), T[1], R(2, 0), R(2, 1), T[2]);
  const cv::Matx33d N(1, 0, -0.5 * (target.width - 1), 0, 1, -0.5 * (target.height - 1), 0, 0, 1);
  cv::Matx33d H = K * M * N;
  return H * (1.0 / H(2, 2));
}

}  // namespace

void CameraPose::Check() const {
  Require(std::isfinite(tilt_deg) && tilt_deg >= 0 && tilt_deg <= 89, ErrorCode::kInvalidArgument,
          "tilt must be in [0, 89] degrees (a plane seen edge-on at 90 degrees has no image)");
  Require(std::isfinite(azimuth_deg) && std::isfinite(roll_deg), ErrorCode::kInvalidArgument, "angles must be finite");
  Require(std::isfinite(size_px) && size_px >= 4 && size_px <= 100000, ErrorCode::kInvalidArgument,
          "target size in the frame must be in 4..100000 pixels");
  Require(std::isfinite(hfov_deg) && hfov_deg >= 5 && hfov_deg <= 150, ErrorCode::kInvalidArgument,
          "field of view must be in [5, 150] degrees");
}

std::array<cv::Point2d, 4> OutlineUnder(const cv::Matx33d& H, cv::Size t) {
  const double w = t.width - 1, h = t.height - 1;
  const cv::Point2d c[4] = {{0, 0}, {w, 0}, {w, h}, {0, h}};
  std::array<cv::Point2d, 4> q;
  for (int i = 0; i < 4; ++i) {
    const cv::Vec3d p = H * cv::Vec3d(c[i].x, c[i].y, 1);
    q[i] = {p[0] / p[2], p[1] / p[2]};
  }
  return q;
}

double LongestEdge(const std::array<cv::Point2d, 4>& q) {
  double m = 0;
  for (int i = 0; i < 4; ++i) m = std::max(m, cv::norm(q[(i + 1) % 4] - q[i]));
  return m;
}

cv::Vec2d LocalScales(const cv::Matx33d& H, cv::Point2d p) {
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  const double x = (H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) / w;
  const double y = (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) / w;
  const double a = (H(0, 0) - x * H(2, 0)) / w, b = (H(0, 1) - x * H(2, 1)) / w;
  const double c = (H(1, 0) - y * H(2, 0)) / w, d = (H(1, 1) - y * H(2, 1)) / w;
  // Singular values of [[a, b], [c, d]].
  const double s1 = a * a + b * b + c * c + d * d, det = std::abs(a * d - b * c);
  const double disc = std::sqrt(std::max(0.0, s1 * s1 - 4 * det * det));
  return {std::sqrt(std::max(0.0, (s1 - disc) / 2)), std::sqrt((s1 + disc) / 2)};
}

cv::Matx33d CameraHomography(cv::Size target, cv::Size frame, const CameraPose& pose) {
  pose.Check();
  Require(target.width >= 2 && target.height >= 2 && frame.width >= 2 && frame.height >= 2,
          ErrorCode::kInvalidArgument, "target and frame must be at least 2x2 pixels");
  const Camera cam = MakeCamera(frame, pose.hfov_deg);
  const cv::Point2d c = pose.centre.x < 0 || pose.centre.y < 0 ? cv::Point2d(cam.cx, cam.cy) : pose.centre;
  cv::Vec3d ray((c.x - cam.cx) / cam.f, (c.y - cam.cy) / cam.f, 1.0);
  ray /= cv::norm(ray);
  const double az = pose.azimuth_deg * kDeg;
  // Plane axes in camera coordinates: tilt about the in-plane axis at the
  // azimuth, roll about the ray, then turn the whole so the ray is its axis.
  const cv::Matx33d R = AlignZ(ray) * RotZ(pose.roll_deg * kDeg) * RotZ(az) * RotX(pose.tilt_deg * kDeg) * RotZ(-az);
  const double side = std::max(target.width, target.height) - 1.0;
  const double w = target.width - 1.0, h = target.height - 1.0;
  // The projected size shrinks as the plane moves away along the ray: find
  // the distance d where the longest edge is size_px by the proportional step
  // d * e / size_px, kept inside a bracket [too near, too far] and bisected
  // (geometrically) whenever the step would leave it or land near an end. Near the camera a steep, off-centre plane
  // grows much faster than 1/d, which a bare proportional update overshoots
  // and can leave unconverged with an outline thousands of pixels long.
  auto edge_at = [&](double dist, cv::Matx33d* Hout) {
    double zmin = 1e300;
    for (const cv::Point2d p : {cv::Point2d(0, 0), cv::Point2d(w, 0), cv::Point2d(w, h), cv::Point2d(0, h)}) {
      const cv::Vec3d P = R * cv::Vec3d(p.x - w / 2, p.y - h / 2, 0) + dist * ray;
      zmin = std::min(zmin, P[2]);
    }
    if (!(zmin > 1e-3 * dist)) return double(INFINITY);  // a corner behind (or at) the camera: "too near"
    *Hout = PlaneHomography(cam, R, dist * ray, target);
    const double e = LongestEdge(OutlineUnder(*Hout, target));
    return std::isfinite(e) ? e : double(INFINITY);
  };
  double d = cam.f * side / pose.size_px;
  double lo = 0, hi = INFINITY;  // distances known too near / too far
  cv::Matx33d H = cv::Matx33d::eye(), best = H;
  double best_err = INFINITY;
  for (int it = 0; it < 100; ++it) {
    cv::Matx33d Hd;
    const double e = edge_at(d, &Hd);
    if (std::isfinite(e)) {
      const double err = std::abs(e - pose.size_px);
      if (err < best_err) {
        best_err = err;
        best = Hd;
      }
      if (err < 1e-3 * pose.size_px) break;
    }
    if (e > pose.size_px) lo = std::max(lo, d);
    else hi = std::min(hi, d);
    double next = std::isfinite(e) ? d * e / pose.size_px : 2 * d;
    if (lo > 0 && std::isfinite(hi)) {
      // Bracketed: take the step only if it lands well inside (in log d);
      // near an end it would creep along one side (false position).
      const double f = std::log(next / lo) / std::log(hi / lo);
      if (!(f > 0.1 && f < 0.9)) next = std::sqrt(lo * hi);
    } else if (!(next > lo && next < hi)) {
      next = std::isfinite(hi) ? 0.5 * hi : 2 * std::max(d, lo);
    }
    d = next;
  }
  Require(best_err < 0.01 * pose.size_px, ErrorCode::kInvalidArgument,
          "no camera distance gives the target an apparent size of " + std::to_string(pose.size_px) + " px in this pose");
  H = best;
  return H;
}

void CameraSceneOptions::Check() const {
  Require(width >= 32 && height >= 32 && width <= 16384 && height <= 16384, ErrorCode::kInvalidArgument,
          "frame size must be within 32..16384 pixels per side");
  Require(min_hfov >= 5 && max_hfov >= min_hfov && max_hfov <= 150, ErrorCode::kInvalidArgument,
          "field of view range must be within [5, 150] degrees");
  Require(min_gain > 0 && max_gain >= min_gain && max_gain <= 4, ErrorCode::kInvalidArgument, "gain range must be in (0, 4]");
  Require(max_offset >= 0 && max_offset <= 128 && gradient >= 0 && gradient < 1, ErrorCode::kInvalidArgument,
          "offset must be in [0, 128] and gradient in [0, 1)");
  Require(max_blur >= 0 && max_blur <= 10 && min_noise >= 0 && max_noise >= min_noise && max_noise <= 100,
          ErrorCode::kInvalidArgument, "blur must be in [0, 10] and noise in [0, 100]");
  Require(jpeg_quality >= 0 && jpeg_quality <= 100, ErrorCode::kInvalidArgument, "JPEG quality must be in 0..100");
  Require(supersample >= 1 && supersample <= 8, ErrorCode::kInvalidArgument, "supersampling must be in 1..8");
}

cv::Mat MakeClutterBackground(cv::Size size, std::uint64_t seed, bool colour) {
  Require(size.width >= 8 && size.height >= 8 && size.width <= 16384 && size.height <= 16384, ErrorCode::kInvalidArgument,
          "clutter size must be within 8..16384 pixels per side");
  std::mt19937_64 rng(seed);
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto Colour = [&] {
    return colour ? cv::Scalar(U(0, 255), U(0, 255), U(0, 255)) : cv::Scalar(U(0, 255));
  };
  cv::Mat tex(std::max(2, size.height / 6), std::max(2, size.width / 6), CV_8UC1), img;
  cv::RNG cvrng(seed ^ 0x9E3779B97F4A7C15ull);
  cvrng.fill(tex, cv::RNG::UNIFORM, 0, 255);
  cv::resize(tex, img, size, 0, 0, cv::INTER_CUBIC);
  if (colour) cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
  const int shapes = int(size.area() / 4000) + 20;
  for (int i = 0; i < shapes; ++i) {
    const cv::Point c(int(U(0, size.width)), int(U(0, size.height)));
    const int r = int(U(3, 40));
    switch (int(U(0, 4))) {
      case 0: cv::rectangle(img, c, c + cv::Point(int(U(-50, 50)), int(U(-50, 50))), Colour(), int(U(0, 2)) ? -1 : 2, cv::LINE_AA); break;
      case 1: cv::circle(img, c, r, Colour(), int(U(0, 2)) ? -1 : 2, cv::LINE_AA); break;
      case 2: cv::line(img, c, c + cv::Point(int(U(-100, 100)), int(U(-100, 100))), Colour(), int(U(1, 4)), cv::LINE_AA); break;
      default: cv::ellipse(img, c, cv::Size(r, int(U(3, 30))), U(0, 180), 0, 360, Colour(), -1, cv::LINE_AA);
    }
  }
  return img;
}

CameraScene MakeCameraScene(const cv::Mat& target, const cv::Mat& background, CameraPose pose,
                            const CameraSceneOptions& o, std::uint64_t seed) {
  o.Check();
  Require(!target.empty() && target.depth() == CV_8U && (target.channels() == 1 || target.channels() == 3),
          ErrorCode::kInvalidArgument, "target must be an 8-bit grey or BGR image");
  std::mt19937_64 rng(seed);
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  const int ch = target.channels(), type = target.type();
  const cv::Size size(o.width, o.height);

  // Background: a random crop of the photo with the frame's aspect ratio.
  cv::Mat img;
  if (!background.empty()) {
    cv::Mat bg = background;
    if (bg.channels() != ch) cv::cvtColor(background, bg, ch == 1 ? cv::COLOR_BGR2GRAY : cv::COLOR_GRAY2BGR);
    const double aspect = double(o.width) / o.height;
    int cw = bg.cols, chh = int(std::lround(cw / aspect));
    if (chh > bg.rows) {
      chh = bg.rows;
      cw = int(std::lround(chh * aspect));
    }
    const double f = U(0.55, 1.0);
    cw = std::max(8, int(cw * f));
    chh = std::max(8, int(chh * f));
    const int x0 = int(U(0, bg.cols - cw + 1)), y0 = int(U(0, bg.rows - chh + 1));
    cv::Mat crop = bg(cv::Rect(std::min(x0, bg.cols - cw), std::min(y0, bg.rows - chh), cw, chh));
    if (U(0, 1) < 0.5) cv::flip(crop, crop, 1);
    cv::resize(crop, img, size, 0, 0, cw > o.width ? cv::INTER_AREA : cv::INTER_CUBIC);
  } else {
    img = cv::Mat(size, type, cv::Scalar::all(U(40, 215)));
  }

  // Geometry: draw the field of view, then a centre where the outline fits.
  pose.hfov_deg = U(o.min_hfov, o.max_hfov);
  CameraScene out;
  cv::Matx33d H;
  {
    CameraPose p = pose;
    p.centre = {-1, -1};
    H = CameraHomography(target.size(), size, p);
    auto q = OutlineUnder(H, target.size());
    out.inside = false;
    if (o.fit) {
      double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
      for (const auto& c : q) {
        x0 = std::min(x0, c.x); y0 = std::min(y0, c.y);
        x1 = std::max(x1, c.x); y1 = std::max(y1, c.y);
      }
      for (int attempt = 0; attempt < 60 && !out.inside; ++attempt) {
        // Shift the ray so the box lands at a random place; perspective
        // changes the box a little, so check the real outline.
        const double m = 2;
        const double lox = m - x0, hix = o.width - 1 - m - x1, loy = m - y0, hiy = o.height - 1 - m - y1;
        if (lox > hix || loy > hiy) break;
        CameraPose pc = pose;
        pc.centre = {0.5 * (o.width - 1) + U(lox, hix), 0.5 * (o.height - 1) + U(loy, hiy)};
        const cv::Matx33d Hc = CameraHomography(target.size(), size, pc);
        const auto qc = OutlineUnder(Hc, target.size());
        bool in = true;
        for (const auto& c : qc) in &= c.x >= 0 && c.y >= 0 && c.x <= o.width - 1 && c.y <= o.height - 1;
        if (in) {
          H = Hc;
          pose = pc;
          out.inside = true;
        }
      }
    }
    if (!out.inside) pose.centre = {0.5 * (o.width - 1), 0.5 * (o.height - 1)};
  }

  // Render the target by supersampling: a source level with about one source
  // pixel per supersampled pixel along the less compressed direction, a
  // bilinear warp at `ss` times the frame, then an area average.
  const int ss = o.supersample;
  const cv::Matx33d S(ss, 0, 0.5 * ss - 0.5, 0, ss, 0.5 * ss - 0.5, 0, 0, 1);
  const cv::Vec2d sc = LocalScales(S * H, {0.5 * (target.cols - 1), 0.5 * (target.rows - 1)});
  cv::Mat src = target;
  cv::Matx33d Hs = S * H;
  if (sc[1] < 0.7) {
    const double f = std::min(1.0, sc[1] / 0.9);
    cv::Mat small;
    cv::resize(target, small, cv::Size(std::max(2, int(std::lround(target.cols * f))),
                                       std::max(2, int(std::lround(target.rows * f)))),
               0, 0, cv::INTER_AREA);
    const double fx = double(small.cols) / target.cols, fy = double(small.rows) / target.rows;
    // small pixel centres -> target pixel centres
    const cv::Matx33d B(1 / fx, 0, 0.5 / fx - 0.5, 0, 1 / fy, 0.5 / fy - 0.5, 0, 0, 1);
    Hs = Hs * B;
    src = small;
  }
  const cv::Size big(o.width * ss, o.height * ss);
  cv::Mat warped, mask;
  cv::warpPerspective(src, warped, cv::Mat(Hs), big, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  cv::Mat ones(src.size(), CV_8UC1, cv::Scalar(255));
  cv::warpPerspective(ones, mask, cv::Mat(Hs), big, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat wf, mf;
  cv::resize(warped, wf, size, 0, 0, cv::INTER_AREA);
  cv::resize(mask, mf, size, 0, 0, cv::INTER_AREA);
  wf.convertTo(wf, CV_32F);
  mf.convertTo(mf, CV_32F, 1.0 / 255);

  // Lighting on the target (premultiplied by coverage), composited over the background.
  const double gain = U(o.min_gain, o.max_gain), offset = U(-o.max_offset, o.max_offset);
  cv::Mat bgf;
  img.convertTo(bgf, CV_32F);
  cv::Mat mfc = mf;
  if (ch == 3) cv::cvtColor(mf, mfc, cv::COLOR_GRAY2BGR);
  cv::Mat comp = bgf.mul(cv::Scalar::all(1.0) - mfc) + wf * gain + mfc * offset;
  // Frame-wide illumination ramp.
  const double gx = U(-o.gradient, o.gradient) / o.width, gy = U(-o.gradient, o.gradient) / o.height;
  cv::Mat ramp(size, CV_32F);
  for (int y = 0; y < o.height; ++y) {
    float* r = ramp.ptr<float>(y);
    for (int x = 0; x < o.width; ++x) r[x] = float(1.0 + gx * (x - o.width / 2.0) + gy * (y - o.height / 2.0));
  }
  if (ch == 3) cv::cvtColor(ramp, ramp, cv::COLOR_GRAY2BGR);
  comp = comp.mul(ramp);

  // Optics and sensor: defocus or motion blur, noise, JPEG.
  if (U(0, 1) < 0.25) {
    const int len = int(U(3, 7));
    cv::Mat k = cv::Mat::zeros(len, len, CV_32F);
    const double a = U(0, CV_PI);
    cv::line(k, {int(std::lround((len - 1) / 2.0 - std::cos(a) * (len - 1) / 2.0)),
                 int(std::lround((len - 1) / 2.0 - std::sin(a) * (len - 1) / 2.0))},
             {int(std::lround((len - 1) / 2.0 + std::cos(a) * (len - 1) / 2.0)),
              int(std::lround((len - 1) / 2.0 + std::sin(a) * (len - 1) / 2.0))},
             cv::Scalar(1.0), 1, cv::LINE_AA);
    k /= cv::sum(k)[0];
    cv::filter2D(comp, comp, -1, k, cv::Point(-1, -1), 0, cv::BORDER_REFLECT_101);
  } else {
    const double blur = U(0, o.max_blur);
    if (blur > 0.2) cv::GaussianBlur(comp, comp, cv::Size(), blur);
  }
  const double noise = U(o.min_noise, o.max_noise);
  if (noise > 0) {
    cv::Mat n(size, CV_MAKETYPE(CV_32F, ch));
    cv::RNG cvrng(rng());
    cvrng.fill(n, cv::RNG::NORMAL, 0, noise);
    comp += n;
  }
  comp.convertTo(img, type);
  if (o.jpeg_quality > 0) {
    std::vector<std::uint8_t> buf;
    cv::imencode(".jpg", img, buf, {cv::IMWRITE_JPEG_QUALITY, o.jpeg_quality});
    img = cv::imdecode(buf, ch == 1 ? cv::IMREAD_GRAYSCALE : cv::IMREAD_COLOR);
  }
  out.image = img;
  out.H = H;
  out.pose = pose;
  return out;
}

}  // namespace mvkp
