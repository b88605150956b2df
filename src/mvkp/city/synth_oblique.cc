#include "mvkp/city/synth_oblique.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

void ObliqueOptions::Check() const {
  auto need = [](bool c, const char* m) { Require(c, ErrorCode::kInvalidArgument, m); };
  need(tilt_deg >= 0 && tilt_deg <= 75, "ObliqueOptions.tilt_deg must be in [0, 75]");
  need(std::isfinite(azimuth_deg), "ObliqueOptions.azimuth_deg must be finite");
  need(gsd_m >= 0.02 && gsd_m <= 5, "ObliqueOptions.gsd_m must be in [0.02, 5]");
  need(width >= 32 && height >= 32 && width <= 8192 && height <= 8192,
       "ObliqueOptions: width and height must be in [32, 8192]");
  need(hfov_deg >= 10 && hfov_deg <= 120, "ObliqueOptions.hfov_deg must be in [10, 120]");
  need(std::isfinite(target.x) && std::isfinite(target.y), "ObliqueOptions.target must be finite");
  need(lighting >= 0 && lighting <= 0.5, "ObliqueOptions.lighting must be in [0, 0.5]");
  need(blur >= 0 && blur <= 5 && noise >= 0 && noise <= 30, "ObliqueOptions: blur in [0, 5], noise in [0, 30]");
  need(jpeg_quality >= 0 && jpeg_quality <= 100, "ObliqueOptions.jpeg_quality must be in [0, 100]");
  need(check_points >= 0 && check_points <= 100000, "ObliqueOptions.check_points must be in [0, 100000]");
}

namespace {

constexpr double kPi = CV_PI;

// The DSM with its gaps filled from the nearest return outside them (gaps:
// no return, and `also` where non-zero).
cv::Mat1f FilledSurface(const cv::Mat1f& depth, const cv::Mat1b& also = {}) {
  cv::Mat1b gap(depth.size());
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) gap(y, x) = std::isfinite(depth(y, x)) && (also.empty() || !also(y, x)) ? 0 : 255;
  if (cv::countNonZero(gap) == 0) return depth.clone();
  Require(cv::countNonZero(gap) < int(gap.total()), ErrorCode::kInvalidArgument,
          "RenderOblique: the depth raster has no return at all");
  cv::Mat1f dist;
  cv::Mat1i label;
  cv::distanceTransform(gap, dist, label, cv::DIST_L2, 3, cv::DIST_LABEL_PIXEL);
  // labels number the zero (valid) pixels in scan order from 1
  std::vector<float> value(1, 0.f);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x)
      if (!gap(y, x)) value.push_back(depth(y, x));
  cv::Mat1f out = depth.clone();
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x)
      if (gap(y, x)) out(y, x) = value[size_t(std::clamp(label(y, x), 0, int(value.size()) - 1))];
  return out;
}

struct Surface {
  cv::Mat1f h;  // metres
  double res = 0.5;
  cv::Mat1f beyond;  // beyond the raster: this (the terrain) at the nearest edge point
  float hmax = 0, hmin = 0;
  // bilinear height at world (x, y) metres
  float At(double x, double y) const {
    double c = x / res, r = -y / res;  // east, north -> column, row
    const cv::Mat1f* m = &h;
    if (c < 0 || r < 0 || c > h.cols - 1 || r > h.rows - 1) {
      c = std::clamp(c, 0.0, double(h.cols - 1)), r = std::clamp(r, 0.0, double(h.rows - 1));
      if (!beyond.empty()) m = &beyond;
    }
    const int c0 = std::min(int(c), h.cols - 2), r0 = std::min(int(r), h.rows - 2);
    const float fc = float(c - c0), fr = float(r - r0);
    const float* a = m->ptr<float>(r0) + c0;
    const float* b = m->ptr<float>(r0 + 1) + c0;
    return (a[0] * (1 - fc) + a[1] * fc) * (1 - fr) + (b[0] * (1 - fc) + b[1] * fc) * fr;
  }
};

// First intersection of the ray C + t d with the surface (t > 0), by marching
// 0.4 depth px horizontally at a time from where the ray drops below the
// highest point, then bisection. Returns false when it leaves without a hit.
bool Intersect(const Surface& s, const cv::Vec3d& C, const cv::Vec3d& d, cv::Vec3d* hit) {
  if (!(d[2] < -1e-9)) return false;
  double t = std::max(0.0, (double(s.hmax) + 0.5 - C[2]) / d[2]);
  const double horiz = std::hypot(d[0], d[1]);
  const double dt = horiz > 1e-9 ? 0.4 * s.res / horiz : 0.5;
  const double t_end = (double(s.hmin) - 1.0 - C[2]) / d[2];
  double prev = t;
  for (int guard = 0; t <= t_end + dt && guard < 1000000; ++guard, prev = t, t += dt) {
    const cv::Vec3d p = C + t * d;
    if (p[2] <= s.At(p[0], p[1])) {
      double a = prev, b = t;
      for (int i = 0; i < 20; ++i) {
        const double m = 0.5 * (a + b);
        const cv::Vec3d q = C + m * d;
        (q[2] <= s.At(q[0], q[1]) ? b : a) = m;
      }
      *hit = C + b * d;
      return true;
    }
  }
  return false;
}

cv::Vec3f Bilinear(const cv::Mat3b& img, double x, double y) {
  const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
  const float fx = float(x - x0), fy = float(y - y0);
  cv::Vec3f out(0, 0, 0);
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int xx = std::clamp(x0 + dx, 0, img.cols - 1), yy = std::clamp(y0 + dy, 0, img.rows - 1);
      const float w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
      const cv::Vec3b& p = img(yy, xx);
      out += w * cv::Vec3f(p[0], p[1], p[2]);
    }
  return out;
}

}  // namespace

ObliqueView RenderOblique(const City& city, const ObliqueOptions& o, std::uint64_t seed) {
  o.Check();
  Require(!city.depth.empty() && !city.photo.empty(), ErrorCode::kInvalidArgument, "RenderOblique: empty city");
  // std::mt19937_64's output is fixed by the standard (the distributions are not)
  std::mt19937_64 gen(seed);
  auto U = [&gen](double a, double b) { return a + (b - a) * double(gen() >> 11) * 0x1.0p-53; };
  ObliqueView v;
  v.options = o;
  v.seed = seed;
  const double res = city.options.res_m;
  Surface s;
  s.h = FilledSurface(city.depth);
  s.res = res;
  double lo = 0, hi = 0;
  cv::minMaxLoc(s.h, &lo, &hi);
  s.hmin = float(lo), s.hmax = float(hi);
  // the terrain (buildings and trees removed, smoothed): the nadir photo's
  // lean displaces a point by its height above it
  cv::Mat1b objects = city.building_id >= 0;
  if (!city.tree_mask.empty()) objects |= city.tree_mask;
  cv::dilate(objects, objects, cv::Mat(), cv::Point(-1, -1), 2);
  Surface ground = s;
  ground.h = FilledSurface(city.depth, objects);
  cv::GaussianBlur(ground.h, ground.h, cv::Size(), 6.0);
  s.beyond = ground.h;  // open ground beyond the raster, no wall at its edge

  // camera: look at the target from the tilt and azimuth, at the distance
  // that gives gsd_m per pixel at the centre (across the view)
  const cv::Matx33d depth_to_photo = city.photo_to_depth.inv();
  cv::Point2d target = o.target;
  if (target.x < 0 || target.y < 0) {
    const cv::Vec3d c = city.photo_to_depth * cv::Vec3d((city.photo.cols - 1) / 2.0, (city.photo.rows - 1) / 2.0, 1);
    target = {c[0] / c[2], c[1] / c[2]};
  }
  const cv::Vec3d G(target.x * res, -target.y * res, s.At(target.x * res, -target.y * res));
  const double tilt = o.tilt_deg * kPi / 180, az = o.azimuth_deg * kPi / 180;
  // camera axes in the world (east, north, up): x right, y down, z along
  // the view, a proper rotation (right x down = look)
  const cv::Vec3d look(std::sin(tilt) * std::sin(az), std::sin(tilt) * std::cos(az), -std::cos(tilt));
  const cv::Vec3d right(std::cos(az), -std::sin(az), 0);
  const cv::Vec3d down = look.cross(right);
  const double f = (o.width / 2.0) / std::tan(o.hfov_deg * kPi / 360);
  const double dist = o.gsd_m * f;
  v.centre_m = G - dist * look;
  Require(v.centre_m[2] > hi + 5, ErrorCode::kInvalidArgument,
          "RenderOblique: the camera would be below the city's roofs (raise gsd_m or lower tilt_deg)");
  v.K = cv::Matx33d(f, 0, (o.width - 1) / 2.0, 0, f, (o.height - 1) / 2.0, 0, 0, 1);
  v.R = cv::Matx33d(right[0], right[1], right[2], down[0], down[1], down[2], look[0], look[1], look[2]);
  const cv::Vec3d t = -(v.R * v.centre_m);
  cv::Matx34d Rt;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) Rt(r, c) = v.R(r, c);
    Rt(r, 3) = t[r];
  }
  v.camera = v.K * Rt;
  const cv::Matx33d Kinv = v.K.inv();
  const cv::Matx33d Rt_inv = v.R.t();

  // the sun, toward it (east, north, up)
  const double saz = city.sun_azimuth_deg * kPi / 180, sel = city.sun_elevation_deg * kPi / 180;
  const cv::Vec3d sun(std::sin(saz) * std::cos(sel), std::cos(saz) * std::cos(sel), std::sin(sel));
  const cv::Point2d lean_px = city.lean * (1.0 / res);  // depth px per metre of height

  auto nadir_px = [&](const cv::Vec3d& X) {
    const double h = std::max(0.0, X[2] - double(ground.At(X[0], X[1])));
    const cv::Point2d q(X[0] / res + lean_px.x * h, -X[1] / res + lean_px.y * h);
    const cv::Vec3d p = depth_to_photo * cv::Vec3d(q.x, q.y, 1);
    return cv::Point2d(p[0] / p[2], p[1] / p[2]);
  };
  auto building_at = [&](double x, double y) {
    const int c = int(std::lround(x / res)), r = int(std::lround(-y / res));
    if (c < 0 || r < 0 || c >= city.building_id.cols || r >= city.building_id.rows) return -1;
    return city.building_id(r, c);
  };
  // facade colours: one per building, muted
  auto facade = [&](int b) {
    std::uint64_t k = std::uint64_t(b + 1) * 0x9e3779b97f4a7c15ull ^ seed;
    k ^= k >> 29;
    const double u1 = double(k & 0xffff) / 65535.0, u2 = double((k >> 16) & 0xffff) / 65535.0,
                 u3 = double((k >> 32) & 0xffff) / 65535.0;
    const double base = 120 + 90 * u1;  // grey level
    return cv::Vec3f(float(base * (0.8 + 0.3 * u2)), float(base * (0.85 + 0.2 * u3)), float(base * (0.9 + 0.25 * u1)));
  };

  v.image.create(o.height, o.width);
  v.building_id.create(o.height, o.width);
  cv::Mat3f img(o.height, o.width);
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      const cv::Vec3d d = cv::normalize(Rt_inv * (Kinv * cv::Vec3d(x, y, 1)));
      cv::Vec3d X;
      cv::Vec3f col(150, 170, 180);  // sky / haze
      int id = -1;
      if (Intersect(s, v.centre_m, d, &X)) {
        // a wall where the surface is steep (a step of the DSM)
        const double e = 0.5 * res;
        const double gx = (s.At(X[0] + e, X[1]) - s.At(X[0] - e, X[1])) / (2 * e);
        const double gy = (s.At(X[0], X[1] + e) - s.At(X[0], X[1] - e)) / (2 * e);
        const double g = std::hypot(gx, gy);
        if (g > 2.5) {
          const cv::Vec3d n(-gx / g, -gy / g, 0);  // outward (downhill)
          id = building_at(X[0] - n[0] * res, X[1] - n[1] * res);
          const double ground = s.At(X[0] + n[0] * 2 * res, X[1] + n[1] * 2 * res);
          const double zf = (X[2] - ground) / 3.0;  // floors of 3 m
          const double along = (-n[1] * X[0] + n[0] * X[1]) / 2.5;  // window bays of 2.5 m
          const bool window = zf - std::floor(zf) > 0.35 && zf - std::floor(zf) < 0.75 &&
                              along - std::floor(along) > 0.25 && along - std::floor(along) < 0.75 && zf > 0.3;
          const cv::Vec3f base = id >= 0 ? facade(id) : cv::Vec3f(90, 110, 95);  // a tree's side
          const double light = 0.35 + 0.65 * std::max(0.0, n.dot(sun));
          col = (window ? cv::Vec3f(75, 62, 55) : base) * float(light);
        } else {
          const cv::Point2d p = nadir_px(X);
          if (p.x >= 0 && p.y >= 0 && p.x <= city.photo.cols - 1 && p.y <= city.photo.rows - 1)
            col = Bilinear(city.photo, p.x, p.y);
          else
            col = cv::Vec3f(95, 125, 110);  // beyond the nadir photo: plain ground
          id = building_at(X[0], X[1]);
        }
      }
      img(y, x) = col;
      v.building_id(y, x) = id;
    }

  // lighting change, blur, noise, JPEG
  const double gain = U(1 - o.lighting, 1 + o.lighting), gamma = U(1 - o.lighting, 1 + o.lighting);
  const cv::Vec3f tint(float(U(0.95, 1.05)), 1.f, float(U(0.95, 1.05)));
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x)
      for (int c = 0; c < 3; ++c)
        img(y, x)[c] = float(255.0 * std::pow(std::clamp(img(y, x)[c] * tint[c] / 255.0, 0.0, 1.0), gamma) * gain);
  const double sigma = U(0.3, std::max(0.3, o.blur));
  if (o.blur > 0) cv::GaussianBlur(img, img, cv::Size(), sigma);
  if (o.noise > 0) {
    cv::Mat3f n(img.size());
    cv::RNG cvr(seed ^ 0x5bd1e995ull);
    cvr.fill(n, cv::RNG::NORMAL, 0, U(1.0, std::max(1.0, o.noise)));
    img += n;
  }
  img.convertTo(v.image, CV_8U);
  if (o.jpeg_quality > 0) {
    std::vector<uchar> buf;
    cv::imencode(".jpg", v.image, buf, {cv::IMWRITE_JPEG_QUALITY, o.jpeg_quality});
    v.image = cv::imdecode(buf, cv::IMREAD_COLOR);
  }

  // check points: roof corners (the DSM just inside the corner), then open
  // ground away from buildings and trees; kept when the camera sees them
  std::vector<std::pair<cv::Vec3d, int>> cand;
  for (size_t b = 0; b < city.footprints.size(); ++b) {
    const auto& fp = city.footprints[b];
    cv::Point2d c(0, 0);
    for (const auto& p : fp) c += cv::Point2d(p);
    c *= 1.0 / std::max<size_t>(1, fp.size());
    for (const auto& p : fp) {
      cv::Point2d in = c - cv::Point2d(p);
      in *= 1.5 / std::max(1e-6, std::hypot(in.x, in.y));
      // the roof just inside the corner (not a concave corner's outside)
      if (building_at((p.x + in.x) * res, -(p.y + in.y) * res) != int(b)) continue;
      const double z = s.At((p.x + in.x) * res, -(p.y + in.y) * res);
      cand.emplace_back(cv::Vec3d(p.x * res, -p.y * res, z), int(b));
    }
  }
  for (int k = 0, tries = 0; k < o.check_points && tries < 20 * o.check_points; ++tries) {
    const int c = int(U(3, city.depth.cols - 4)), r = int(U(3, city.depth.rows - 4));
    bool open = true;
    for (int dy = -3; dy <= 3 && open; ++dy)
      for (int dx = -3; dx <= 3 && open; ++dx)
        open = city.building_id(r + dy, c + dx) < 0 && (city.tree_mask.empty() || !city.tree_mask(r + dy, c + dx)) &&
               std::isfinite(city.depth(r + dy, c + dx));
    if (!open) continue;
    cand.emplace_back(cv::Vec3d(c * res, -r * res, s.At(c * res, -r * res)), -1);
    ++k;
  }
  for (const auto& [X, b] : cand) {
    if (int(v.checks.size()) >= o.check_points) break;
    const cv::Vec4d Xh(X[0], X[1], X[2], 1);
    const cv::Vec3d p = v.camera * Xh;
    if (!(p[2] > 0)) continue;
    const cv::Point2d px(p[0] / p[2], p[1] / p[2]);
    if (px.x < 0 || px.y < 0 || px.x > o.width - 1 || px.y > o.height - 1) continue;
    const cv::Point2d np = nadir_px(X);
    if (np.x < 0 || np.y < 0 || np.x > city.photo.cols - 1 || np.y > city.photo.rows - 1) continue;
    cv::Vec3d hit;
    const cv::Vec3d d = cv::normalize(X - v.centre_m);
    if (!Intersect(s, v.centre_m, d, &hit) || cv::norm(hit - X) > 0.75) continue;  // hidden
    ObliqueCheckPoint cp;
    cp.world = {X[0], X[1], X[2]};
    cp.depth_px = {X[0] / res, -X[1] / res};
    cp.nadir_px = np;
    cp.oblique_px = px;
    cp.building = b;
    v.checks.push_back(cp);
  }
  return v;
}

void SaveOblique(const ObliqueView& v, const std::string& dir, const std::string& stem) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw Error(ErrorCode::kIo, dir + ": cannot create output directory");
  const std::string img = (fs::path(dir) / (stem + ".png")).string();
  bool ok = false;
  try {
    ok = cv::imwrite(img, v.image);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw Error(ErrorCode::kIo, img + ": cannot write");
  using nlohmann::json;
  auto mat = [](const auto& m, int rows, int cols) {
    json a = json::array();
    for (int r = 0; r < rows; ++r) {
      json row = json::array();
      for (int c = 0; c < cols; ++c) row.push_back(m(r, c));
      a.push_back(row);
    }
    return a;
  };
  json j;
  j["image"] = stem + ".png";
  j["seed"] = v.seed;
  j["camera"] = mat(v.camera, 3, 4);
  j["camera_note"] = "3x4, world metres east-north-up (x = depth column * res_m, y = -depth row * res_m, z = DSM "
                     "height) -> oblique pixel, pixel centres at integers";
  j["K"] = mat(v.K, 3, 3);
  j["R"] = mat(v.R, 3, 3);
  j["centre_m"] = {v.centre_m[0], v.centre_m[1], v.centre_m[2]};
  const ObliqueOptions& o = v.options;
  j["options"] = {{"tilt_deg", o.tilt_deg},   {"azimuth_deg", o.azimuth_deg}, {"gsd_m", o.gsd_m},
                  {"width", o.width},         {"height", o.height},           {"hfov_deg", o.hfov_deg},
                  {"lighting", o.lighting},   {"blur", o.blur},               {"noise", o.noise},
                  {"jpeg_quality", o.jpeg_quality}};
  json cps = json::array();
  for (const auto& c : v.checks)
    cps.push_back({{"world_m", {c.world.x, c.world.y, c.world.z}},
                   {"depth_px", {c.depth_px.x, c.depth_px.y}},
                   {"nadir_px", {c.nadir_px.x, c.nadir_px.y}},
                   {"oblique_px", {c.oblique_px.x, c.oblique_px.y}},
                   {"building", c.building}});
  j["check_points"] = cps;
  const std::string path = (fs::path(dir) / (stem + ".json")).string();
  std::ofstream f(path);
  f << j.dump(1) << "\n";
  if (!f) throw Error(ErrorCode::kIo, path + ": cannot write");
}

double CheckPointError(const cv::Matx34d& P, const ObliqueView& v) {
  if (v.checks.empty()) return std::numeric_limits<double>::infinity();
  double sum = 0;
  for (const auto& c : v.checks) {
    const cv::Vec3d p = P * cv::Vec4d(c.world.x, c.world.y, c.world.z, 1);
    if (!(p[2] > 0)) return std::numeric_limits<double>::infinity();
    sum += std::hypot(p[0] / p[2] - c.oblique_px.x, p[1] / p[2] - c.oblique_px.y);
  }
  return sum / double(v.checks.size());
}

}  // namespace mvkp
