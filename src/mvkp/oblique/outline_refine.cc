#include "mvkp/oblique/outline_refine.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

namespace {

constexpr int kBins = 4;  // edge orientations, modulo 180 degrees

int OrientationBin(double dx, double dy) {
  double a = std::atan2(dy, dx);
  if (a < 0) a += CV_PI;
  if (a >= CV_PI) a -= CV_PI;
  return int(std::floor(a / (CV_PI / kBins) + 0.5)) % kBins;
}

}  // namespace

// Distance to, and position of, the nearest edge pixel of each orientation.
struct OutlineEdgeMaps {
  cv::Size size;
  std::array<cv::Mat1f, kBins> dist;
  std::array<cv::Mat1i, kBins> label;
  std::array<std::vector<cv::Point>, kBins> where;  // label -> edge pixel
};

namespace {

OutlineEdgeMaps BuildEdgeMaps(const cv::Mat& view, const OutlineRefineOptions& o) {
  cv::Mat g, edges, gx, gy;
  cv::GaussianBlur(view, g, cv::Size(), o.edge_blur);
  cv::Canny(g, edges, o.canny_low, o.canny_high);
  cv::Sobel(g, gx, CV_32F, 1, 0);
  cv::Sobel(g, gy, CV_32F, 0, 1);
  std::array<cv::Mat1b, kBins> free;
  for (auto& f : free) f = cv::Mat1b(view.size(), 255);
  for (int y = 0; y < view.rows; ++y)
    for (int x = 0; x < view.cols; ++x)
      if (edges.at<uchar>(y, x)) free[OrientationBin(gx.at<float>(y, x), gy.at<float>(y, x))](y, x) = 0;
  OutlineEdgeMaps m;
  m.size = view.size();
  for (int b = 0; b < kBins; ++b) {
    cv::distanceTransform(free[b], m.dist[b], m.label[b], cv::DIST_L2, cv::DIST_MASK_5, cv::DIST_LABEL_PIXEL);
    int top = 0;
    for (int y = 0; y < view.rows; ++y)
      for (int x = 0; x < view.cols; ++x)
        if (!free[b](y, x)) top = std::max(top, m.label[b](y, x));
    m.where[b].assign(std::size_t(top) + 1, cv::Point(-1, -1));
    for (int y = 0; y < view.rows; ++y)
      for (int x = 0; x < view.cols; ++x)
        if (!free[b](y, x)) m.where[b][std::size_t(m.label[b](y, x))] = cv::Point(x, y);
  }
  return m;
}

bool Project(const cv::Matx34d& P, const cv::Point3d& X, cv::Point2d* u) {
  const cv::Vec3d v = P * cv::Vec4d(X.x, X.y, X.z, 1);
  if (!(v[2] > 1e-9)) return false;
  *u = {v[0] / v[2], v[1] / v[2]};
  return std::isfinite(u->x) && std::isfinite(u->y);
}

}  // namespace

void OutlineRefineOptions::Check() const {
  bool radii_ok = !radii.empty();
  for (double r : radii) radii_ok = radii_ok && r >= 0.5 && r <= 64;
  Require(min_step_m > 0 && max_points >= 10 && radii_ok && min_pairs >= 6 && passes >= 1 && passes <= 20 && edge_blur >= 0 && edge_blur <= 10 &&
              canny_low >= 0 && canny_high >= canny_low && keep_px >= 0 && min_gain >= 0,
          ErrorCode::kInvalidArgument,
          "OutlineRefineOptions: min_step_m > 0, max_points >= 10, radii in [0.5, 64] (at least one), "
          "min_pairs >= 6, passes in [1, 20], edge_blur in [0, 10], 0 <= canny_low <= canny_high, keep_px >= 0, min_gain >= 0");
}

OutlineRefiner::OutlineRefiner(const cv::Mat1f& depth, double res_m, const OutlineRefineOptions& o) : options_(o) {
  o.Check();
  Require(!depth.empty() && res_m > 0 && std::isfinite(res_m), ErrorCode::kInvalidArgument,
          "OutlineRefiner: need a depth raster and res_m > 0");
  std::vector<float> v;
  for (float z : depth)
    if (std::isfinite(z)) v.push_back(z);
  Require(!v.empty(), ErrorCode::kInvalidArgument, "OutlineRefiner: the depth raster has no data");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  cv::Mat1f filled = depth.clone();
  for (float& z : filled)
    if (!std::isfinite(z)) z = v[v.size() / 2];
  cv::Mat1f gx, gy;
  cv::Sobel(filled, gx, CV_32F, 1, 0);
  cv::Sobel(filled, gy, CV_32F, 0, 1);
  std::vector<cv::Point> cells;
  for (int y = 1; y + 1 < depth.rows; ++y)
    for (int x = 1; x + 1 < depth.cols; ++x) {
      const float z = depth(y, x);
      if (!std::isfinite(z)) continue;
      float lo = z;  // lowest return among the 4 neighbours (no-data ones do not count)
      for (const cv::Point d : {cv::Point(1, 0), cv::Point(-1, 0), cv::Point(0, 1), cv::Point(0, -1)}) {
        const float n = depth(y + d.y, x + d.x);
        if (std::isfinite(n)) lo = std::min(lo, n);
      }
      if (z - lo >= o.min_step_m && std::hypot(gx(y, x), gy(y, x)) > 1e-6) cells.emplace_back(x, y);
    }
  const std::size_t stride = std::max<std::size_t>(1, (cells.size() + o.max_points - 1) / o.max_points);
  for (std::size_t i = 0; i < cells.size(); i += stride) {
    const cv::Point c = cells[i];
    const double nx = gx(c), ny = -gy(c), n = std::hypot(nx, ny);  // rows run south: north = -row
    world_.emplace_back(c.x * res_m, -c.y * res_m, double(depth(c)));
    normal_.emplace_back(nx / n, ny / n);
  }
}

std::shared_ptr<const OutlineEdgeMaps> OutlineRefiner::EdgeMaps(const cv::Mat& view) const {
  Require(!view.empty() && view.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "OutlineRefiner: an 8-bit grey view is required");
  return std::make_shared<const OutlineEdgeMaps>(BuildEdgeMaps(view, options_));
}

OutlineRefinement OutlineRefiner::Refine(const cv::Mat& view, const cv::Matx33d& K, const NadirLifter& lifter,
                                         ViewPose* pose) const {
  Require(!view.empty() && view.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "OutlineRefiner: an 8-bit grey view is required");
  Require(pose != nullptr && pose->ok, ErrorCode::kInvalidArgument, "OutlineRefiner: a camera to refine is required");
  std::shared_ptr<const OutlineEdgeMaps> maps;  // built only when enough outline points are seen
  return Run(OutlineEdgeMaps{view.size(), {}, {}, {}}, K, lifter, options_.radii, false, pose, &view, &maps);
}

OutlineRefinement OutlineRefiner::Fit(const OutlineEdgeMaps& maps, const cv::Matx33d& K, const NadirLifter& lifter,
                                      const std::vector<double>& radii, ViewPose* pose) const {
  Require(pose != nullptr && pose->ok && !radii.empty(), ErrorCode::kInvalidArgument,
          "OutlineRefiner::Fit: a camera and pairing radii are required");
  for (double r : radii)
    Require(r >= 0.5 && r <= 256, ErrorCode::kInvalidArgument, "OutlineRefiner::Fit: radii must be in [0.5, 256]");
  return Run(maps, K, lifter, radii, true, pose, nullptr, nullptr);
}

double OutlineRefiner::Score(const OutlineEdgeMaps& maps, const cv::Matx34d& P, double radius, int* inside) const {
  int in = 0, hit = 0;
  for (std::size_t i = 0; i < world_.size(); ++i) {
    cv::Point2d u, u2;
    const cv::Point3d& w = world_[i];
    const cv::Point3d w2(w.x + 0.5 * normal_[i][0], w.y + 0.5 * normal_[i][1], w.z);
    if (!Project(P, w, &u) || !Project(P, w2, &u2)) continue;
    // bounded before rounding: a rough camera projects points anywhere
    if (!(u.x > -0.5 && u.y > -0.5 && u.x < maps.size.width - 0.5 && u.y < maps.size.height - 0.5)) continue;
    const int x = int(std::lround(u.x)), y = int(std::lround(u.y));
    if (x < 0 || y < 0 || x >= maps.size.width || y >= maps.size.height) continue;
    if (cv::norm(u2 - u) < 0.05) continue;
    ++in;
    hit += maps.dist[std::size_t(OrientationBin(u2.x - u.x, u2.y - u.y))](y, x) <= radius;
  }
  if (inside) *inside = in;
  return in ? double(hit) / in : 0.0;
}

OutlineRefinement OutlineRefiner::Run(const OutlineEdgeMaps& given, const cv::Matx33d& K, const NadirLifter& lifter,
                                      const std::vector<double>& radii, bool always, ViewPose* pose,
                                      const cv::Mat* view_image, std::shared_ptr<const OutlineEdgeMaps>* built) const {
  const cv::Size view = given.size;
  OutlineRefinement out;
  const cv::Matx34d P0 = pose->camera;
  // outline points the first camera sees, each with the orientation bin its
  // edge should have (the step direction, projected)
  std::vector<cv::Point3d> X;
  std::vector<int> bin;
  for (std::size_t i = 0; i < world_.size(); ++i) {
    cv::Point2d u, u2;
    const cv::Point3d& w = world_[i];
    const cv::Point3d w2(w.x + 0.5 * normal_[i][0], w.y + 0.5 * normal_[i][1], w.z);
    if (!Project(P0, w, &u) || !Project(P0, w2, &u2)) continue;
    if (u.x < 0 || u.y < 0 || u.x > view.width - 1 || u.y > view.height - 1) continue;
    if (cv::norm(u2 - u) < 0.05) continue;
    if (!lifter.Visible(w, pose->centre_m, 0.5)) continue;
    X.push_back(w);
    bin.push_back(OrientationBin(u2.x - u.x, u2.y - u.y));
  }
  out.visible = int(X.size());
  if (out.visible < options_.min_pairs) return out;
  out.ran = true;
  if (view_image) *built = EdgeMaps(*view_image);
  const OutlineEdgeMaps& maps = view_image ? **built : given;

  auto pair = [&](const cv::Matx34d& P, double radius, std::vector<cv::Point3f>* obj, std::vector<cv::Point2f>* img) {
    obj->clear();
    img->clear();
    for (std::size_t i = 0; i < X.size(); ++i) {
      cv::Point2d u;
      if (!Project(P, X[i], &u)) continue;
      if (!(u.x > -0.5 && u.y > -0.5 && u.x < view.width - 0.5 && u.y < view.height - 0.5)) continue;
      const int x = int(std::lround(u.x)), y = int(std::lround(u.y));
      if (x < 0 || y < 0 || x >= view.width || y >= view.height) continue;
      const int b = bin[i];
      if (!(maps.dist[b](y, x) <= radius)) continue;
      const cv::Point e = maps.where[b][std::size_t(maps.label[b](y, x))];
      if (e.x < 0) continue;
      obj->emplace_back(float(X[i].x), float(X[i].y), float(X[i].z));
      img->emplace_back(float(e.x), float(e.y));
    }
  };

  std::vector<cv::Point3f> obj;
  std::vector<cv::Point2f> img;
  pair(P0, radii.back(), &obj, &img);
  out.first_pairs = int(obj.size());
  cv::Mat rvec, tvec;
  cv::Rodrigues(cv::Mat(pose->R), rvec);
  tvec = cv::Mat(pose->t).clone();
  cv::Matx34d P = P0;
  // the world is in metres far from the origin: fit about the points' mean
  cv::Point3d origin(0, 0, 0);
  for (const auto& w : X) origin += w;
  origin *= 1.0 / double(X.size());
  std::vector<double> rounds;
  for (int k = 0; k < options_.passes; ++k) rounds.insert(rounds.end(), radii.begin(), radii.end());
  for (double radius : rounds) {
    pair(P, radius, &obj, &img);
    if (int(obj.size()) < options_.min_pairs) return out;
    for (auto& w : obj) w -= cv::Point3f(origin);
    // t about the origin: t' = t + R origin
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    cv::Mat t0 = tvec + R * cv::Mat(cv::Vec3d(origin.x, origin.y, origin.z));
    cv::solvePnP(obj, img, cv::Mat(K), cv::noArray(), rvec, t0, true, cv::SOLVEPNP_ITERATIVE);
    cv::Rodrigues(rvec, R);
    tvec = t0 - R * cv::Mat(cv::Vec3d(origin.x, origin.y, origin.z));
    cv::Matx33d Rx;
    R.copyTo(Rx);
    P = CameraMatrix(K, Rx, cv::Vec3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  }
  pair(P, radii.back(), &obj, &img);
  out.pairs = int(obj.size());
  if (out.pairs < options_.min_pairs) return out;
  std::vector<double> moves;
  for (const auto& w : obj) {
    cv::Point2d a, b;
    if (Project(P0, cv::Point3d(w), &a) && Project(P, cv::Point3d(w), &b)) moves.push_back(cv::norm(a - b));
  }
  if (moves.empty()) return out;
  std::nth_element(moves.begin(), moves.begin() + moves.size() / 2, moves.end());
  out.move_px = moves[moves.size() / 2];
  if (always || (out.move_px > options_.keep_px && out.pairs >= options_.min_gain * out.first_pairs)) {
    cv::Matx33d R;
    cv::Mat Rm;
    cv::Rodrigues(rvec, Rm);
    Rm.copyTo(R);
    const cv::Vec3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    pose->R = R;
    pose->t = t;
    pose->camera = P;
    pose->centre_m = -(R.t() * t);
    out.replaced = true;
  }
  return out;
}

}  // namespace mvkp
