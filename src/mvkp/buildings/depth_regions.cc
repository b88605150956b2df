// Building regions from a LiDAR depth image (thesis §7.2.1); see depth_regions.h.
#include "mvkp/buildings/depth_regions.h"

#include <algorithm>
#include <cfloat>
#include <climits>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {

void DepthSegmentOptions::Check() const {
  auto need = [](bool ok, const std::string& what) { Require(ok, ErrorCode::kInvalidArgument, "depth segmentation: " + what); };
  need(ground_window >= 3, "ground_window must be >= 3 px");
  need(grid_step >= 1, "grid_step must be >= 1 px");
  need(std::isfinite(water_level) && water_level > 0, "water_level must be > 0 m");
  need(std::isfinite(range_max) && range_max >= 0, "range_max must be >= 0 m");
  need(area_min >= 1, "area_min must be >= 1 px");
  need(lcc_radius >= 1 && lcc_radius <= 15, "lcc_radius must be in [1, 15] px");
  need(lcc_sigma > 0, "lcc_sigma must be > 0 px");
  need(lcc_percent >= 0 && lcc_percent <= 1, "lcc_percent must be in [0, 1]");
  need(std::isfinite(lcc_noise) && lcc_noise >= 0, "lcc_noise must be >= 0 m");
  need(std::isfinite(lcc_slope) && lcc_slope >= 0 && lcc_slope <= 10, "lcc_slope must be in [0, 10] m per px");
  need(lcc_min_support >= 0 && lcc_min_support <= 1, "lcc_min_support must be in [0, 1]");
  need(refine_iterations >= 0, "refine_iterations must be >= 0");
  need(min_area >= 0, "min_area must be >= 0 px");
  need(min_width_px >= 0 && std::isfinite(min_width_px), "min_width_px must be >= 0 px");
  need(merge_corner_px >= 0 && merge_area_ratio >= 0, "merge thresholds must be >= 0");
}

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Pads the columns of m by p on both sides with the odd mirror
// 2 m(edge) - m(edge -+ i); FLT_MAX (no data) stays FLT_MAX.
cv::Mat1f OddPad(const cv::Mat1f& m, int p) {
  cv::Mat1f out(m.rows, m.cols + 2 * p);
  for (int y = 0; y < m.rows; ++y) {
    const float* src = m[y];
    float* dst = out[y];
    std::copy(src, src + m.cols, dst + p);
    const float left = src[0], right = src[m.cols - 1];
    for (int i = 1; i <= p; ++i) {
      const float a = src[std::min(i, m.cols - 1)], b = src[std::max(0, m.cols - 1 - i)];
      dst[p - i] = left == FLT_MAX || a == FLT_MAX ? FLT_MAX : 2 * left - a;
      dst[p + m.cols - 1 + i] = right == FLT_MAX || b == FLT_MAX ? FLT_MAX : 2 * right - b;
    }
  }
  return out;
}

// Local ground. A grey-scale opening (erosion then dilation: exact on planar
// slopes) of the block minima gives a lower envelope; it is computed on the
// residual to a least-squares plane with mirrored borders, so that a slope does
// not bend it at the image border. The envelope is then lifted to the mean of
// the pixels within ground_tolerance above it (min filters sit on the noise
// floor), smoothed, and mapped back to full size.
cv::Mat1f EstimateGround(const cv::Mat1f& d, int window, float fill) {
  constexpr float kGroundTolerance = 1.0f;  // m
  const int b = std::max(1, window / 24);
  const int gw = (d.cols + b - 1) / b, gh = (d.rows + b - 1) / b;
  cv::Mat1f blocks(gh, gw, FLT_MAX);
  for (int y = 0; y < d.rows; ++y) {
    const float* row = d[y];
    float* brow = blocks[y / b];
    for (int x = 0; x < d.cols; ++x)
      if (!std::isnan(row[x])) brow[x / b] = std::min(brow[x / b], row[x]);
  }
  // Plane through the block minima (least squares), removed before the opening.
  cv::Matx33d ata = cv::Matx33d::zeros();
  cv::Vec3d atb(0, 0, 0);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x)
      if (blocks(y, x) != FLT_MAX) {
        const cv::Vec3d a(x, y, 1);
        ata += a * a.t();
        atb += a * static_cast<double>(blocks(y, x));
      }
  cv::Vec3d plane(0, 0, fill);
  if (cv::determinant(ata) > 1e-9) cv::solve(cv::Mat(ata), cv::Mat(atb), plane, cv::DECOMP_SVD);
  auto trend = [&](int x, int y) { return static_cast<float>(plane[0] * x + plane[1] * y + plane[2]); };
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x)
      if (blocks(y, x) != FLT_MAX) blocks(y, x) -= trend(x, y);
  const int k = std::max(3, (window + b - 1) / b) | 1;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, {k, k});
  // Opening of the residual, once with even and once with odd mirroring at
  // the border: even is exact on flat ground, odd on a constant slope (where
  // even lowers the border by slope * window / 2), and a building near the
  // border makes a pit only in the odd mirror. Both are lower envelopes, so
  // their maximum is the better one.
  auto opening = [&](const cv::Mat1f& padded) {
    cv::Mat1f eroded, dilated;
    cv::erode(padded, eroded, kernel, {-1, -1}, 1, cv::BORDER_CONSTANT, cv::Scalar(FLT_MAX));
    for (float& v : eroded)
      if (v == FLT_MAX) v = 0;  // window without any data: the plane
    cv::dilate(eroded, dilated, kernel, {-1, -1}, 1, cv::BORDER_CONSTANT, cv::Scalar(-FLT_MAX));
    return cv::Mat1f(dilated(cv::Rect(k / 2, k / 2, gw, gh)).clone());
  };
  cv::Mat1f even;
  cv::copyMakeBorder(blocks, even, k / 2, k / 2, k / 2, k / 2, cv::BORDER_REFLECT);
  cv::Mat1f opened = opening(even);
  cv::Mat1f odd = OddPad(OddPad(blocks, k / 2).t(), k / 2).t();
  opened = cv::max(opened, opening(odd));
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) opened(y, x) += trend(x, y);
  // Lift to the mean of the near-ground pixels (normalised box average).
  cv::Mat1f sum = cv::Mat1f::zeros(gh, gw), cnt = cv::Mat1f::zeros(gh, gw);
  for (int y = 0; y < d.rows; ++y) {
    const float* row = d[y];
    const float* g = opened[y / b];
    float* s = sum[y / b];
    float* c = cnt[y / b];
    for (int x = 0; x < d.cols; ++x) {
      const float r = row[x] - g[x / b];
      if (r < kGroundTolerance) s[x / b] += r, c[x / b] += 1;  // false for NaN
    }
  }
  const int lift = std::max(3, k / 2) | 1;
  cv::blur(sum, sum, {lift, lift}, {-1, -1}, cv::BORDER_REFLECT);
  cv::blur(cnt, cnt, {lift, lift}, {-1, -1}, cv::BORDER_REFLECT);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x)
      if (cnt(y, x) > 0) opened(y, x) += sum(y, x) / cnt(y, x);
  cv::blur(opened, opened, {3, 3}, {-1, -1}, cv::BORDER_REPLICATE);
  if (b == 1) return opened;
  // cv::resize maps block centres ((j + 0.5) b - 0.5) bilinearly to pixels.
  cv::Mat1f full;
  cv::resize(opened, full, {gw * b, gh * b}, 0, 0, cv::INTER_LINEAR);
  return full(cv::Rect(0, 0, d.cols, d.rows)).clone();
}

struct Offset {
  int dx, dy;
  float factor;  // 1 - exp(-r^2 / (2 sigma^2))
  float slack;   // lcc_noise + r lcc_slope, metres
};

class Segmenter {
 public:
  Segmenter(const cv::Mat1f& h, const DepthSegmentOptions& o) : o_(o), h_(h), w_(h.cols), ht_(h.rows) {
    wl_low_ = o.water_level - o.range_max * (1.0f - std::exp(-4.0f));
    const int r = o.lcc_radius;
    for (int dy = -r; dy <= r; ++dy)
      for (int dx = -r; dx <= r; ++dx) {
        const double rr = dx * dx + dy * dy;
        if (rr == 0 || rr > (r + 0.5) * (r + 0.5)) continue;
        offsets_.push_back({dx, dy, static_cast<float>(1.0 - std::exp(-rr / (2 * o.lcc_sigma * o.lcc_sigma))),
                            static_cast<float>(o.lcc_noise + std::sqrt(rr) * o.lcc_slope)});
      }
    lcc_.assign(static_cast<size_t>(w_) * ht_, 0);
    stamp_.assign(static_cast<size_t>(w_) * ht_, 0);
    covered_.assign(static_cast<size_t>(w_) * ht_, 0);
  }

  std::vector<BuildingRegion> Run() {
    std::vector<std::pair<float, int>> markers = Markers();
    std::sort(markers.begin(), markers.end(), [](auto& a, auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
    std::vector<BuildingRegion> regions;
    std::vector<int> pixels;
    for (const auto& [height, idx] : markers) {
      if (o_.skip_covered_markers && covered_[idx]) continue;
      Grow(idx, &pixels);
      for (int p : pixels) covered_[p] = 1;
      BuildingRegion region;
      if (Finish(pixels, &region)) regions.push_back(std::move(region));
    }
    return Merge(std::move(regions));
  }

 private:
  float H(int idx) const { return h_.ptr<float>()[idx]; }

  // Marker conditions: above WL, passes the LCC, highest such pixel of its cell.
  std::vector<std::pair<float, int>> Markers() {
    std::vector<std::pair<float, int>> markers, cell;
    const int s = o_.grid_step;
    for (int y0 = 0; y0 < ht_; y0 += s)
      for (int x0 = 0; x0 < w_; x0 += s) {
        cell.clear();
        for (int y = y0; y < std::min(ht_, y0 + s); ++y) {
          const float* row = h_[y];
          for (int x = x0; x < std::min(w_, x0 + s); ++x)
            if (row[x] >= o_.water_level) cell.push_back({row[x], y * w_ + x});
        }
        std::sort(cell.begin(), cell.end(), [](auto& a, auto& b) { return a.first > b.first; });
        for (const auto& c : cell)
          if (Lcc(c.second)) {
            markers.push_back(c);
            break;
          }
      }
    return markers;
  }

  // Local consistency check, cached per pixel. Num counts the neighbours with
  // data above the lowest dynamic water level: ground beyond a roof edge is
  // the other side of a depth edge, not roof noise, and is not scanned.
  bool Lcc(int idx) {
    uint8_t& state = lcc_[idx];
    if (state) return state == 1;
    const float c = H(idx);
    const int x = idx % w_, y = idx / w_;
    int num = 0, consistent = 0;
    for (const Offset& off : offsets_) {
      const int xx = x + off.dx, yy = y + off.dy;
      if (xx < 0 || yy < 0 || xx >= w_ || yy >= ht_) continue;
      const float v = h_(yy, xx);
      if (!(v >= wl_low_)) continue;  // NaN or ground
      ++num;
      consistent += std::fabs(v - c) < off.factor * c + off.slack;
    }
    const bool pass = c >= wl_low_ && num >= o_.lcc_min_support * static_cast<double>(offsets_.size()) &&
                      consistent >= o_.lcc_percent * num;
    state = pass ? 1 : 2;
    return pass;
  }

  float DynamicWaterLevel(size_t area) const {
    if (area >= o_.area_min) return o_.water_level;
    const double t = 4.0 * (static_cast<double>(area) - o_.area_min) / o_.area_min;
    return static_cast<float>(o_.water_level - (1.0 - std::exp(t)) * o_.range_max);
  }

  // Watershed-style growth: highest pending pixel first, stopped by the three
  // boundary conditions of §7.2.1.
  void Grow(int seed, std::vector<int>* pixels) {
    pixels->clear();
    const int id = ++region_id_;
    std::priority_queue<std::pair<float, int>> queue;
    queue.push({H(seed), seed});
    stamp_[seed] = id;
    while (!queue.empty()) {
      const auto [v, idx] = queue.top();
      queue.pop();
      const float wl = DynamicWaterLevel(pixels->size());
      if (!(v >= wl)) continue;  // (a) below the dynamic water level
      const int x = idx % w_, y = idx / w_;
      auto fails = [&](int xx, int yy) { return xx < 0 || yy < 0 || xx >= w_ || yy >= ht_ || !(h_(yy, xx) >= wl); };
      if ((fails(x - 1, y) && fails(x + 1, y)) || (fails(x, y - 1) && fails(x, y + 1))) continue;  // (b) fully isolated
      if (!Lcc(idx)) continue;                                                                       // (c) LCC
      pixels->push_back(idx);
      auto push = [&](int xx, int yy) {
        if (xx < 0 || yy < 0 || xx >= w_ || yy >= ht_) return;
        const int q = yy * w_ + xx;
        if (stamp_[q] == id) return;
        stamp_[q] = id;
        const float hv = H(q);
        if (hv >= wl_low_) queue.push({hv, q});
      };
      push(x - 1, y);
      push(x + 1, y);
      push(x, y - 1);
      push(x, y + 1);
    }
  }

  // Refinement (majority filling in the bounding box), outer contour, area,
  // median height. False for regions below min_area.
  bool Finish(const std::vector<int>& pixels, BuildingRegion* region) {
    if (pixels.empty()) return false;
    int x0 = w_, y0 = ht_, x1 = -1, y1 = -1;
    for (int p : pixels) {
      const int x = p % w_, y = p / w_;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
    }
    // Mask with a 1 px empty frame: pixel (x, y) at (x - x0 + 1, y - y0 + 1).
    cv::Mat1b mask = cv::Mat1b::zeros(y1 - y0 + 3, x1 - x0 + 3);
    for (int p : pixels) mask(p / w_ - y0 + 1, p % w_ - x0 + 1) = 1;
    cv::Mat1b next;
    for (int it = 0; it < o_.refine_iterations; ++it) {
      mask.copyTo(next);
      bool changed = false;
      for (int y = 1; y + 1 < mask.rows; ++y) {
        const uint8_t *up = mask[y - 1], *row = mask[y], *dn = mask[y + 1];
        for (int x = 1; x + 1 < mask.cols; ++x) {
          if (row[x]) continue;
          const int n = up[x - 1] + up[x] + up[x + 1] + row[x - 1] + row[x + 1] + dn[x - 1] + dn[x] + dn[x + 1];
          if (n >= 5) next(y, x) = 1, changed = true;
        }
      }
      std::swap(mask, next);
      if (!changed) break;
    }
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, {x0 - 1, y0 - 1});
    if (contours.empty()) return false;
    size_t best = 0;
    for (size_t i = 1; i < contours.size(); ++i)
      if (contours[i].size() > contours[best].size()) best = i;
    std::vector<cv::Point>& contour = contours[best];
    cv::Mat1b filled = cv::Mat1b::zeros(mask.size());
    cv::drawContours(filled, contours, static_cast<int>(best), 1, cv::FILLED, cv::LINE_8, cv::noArray(), INT_MAX,
                     cv::Point(1 - x0, 1 - y0));
    region->area = cv::countNonZero(filled);
    if (region->area < o_.min_area) return false;
    // Width (not in the thesis): hedges and walls pass the water level in
    // strips 2-4 px wide; no building is that narrow. The widest inscribed
    // disc: twice the largest distance to the outside.
    if (o_.min_width_px > 0) {
      cv::Mat1f dist;
      cv::distanceTransform(filled, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
      double widest = 0;
      cv::minMaxLoc(dist, nullptr, &widest);
      if (2 * widest < o_.min_width_px) return false;
    }
    // Roughness: median over the region of the smaller absolute second
    // difference (x or y). Zero on planar and pitched roofs (ridges included:
    // along the ridge it vanishes), large on canopies.
    std::vector<float> curv;
    curv.reserve(pixels.size());
    for (int y = 1; y + 1 < mask.rows; ++y)
      for (int x = 1; x + 1 < mask.cols; ++x) {
        if (!mask(y, x) || !mask(y, x - 1) || !mask(y, x + 1) || !mask(y - 1, x) || !mask(y + 1, x)) continue;
        const int gx = x + x0 - 1, gy = y + y0 - 1;
        const float c = h_(gy, gx);
        const float ax = std::fabs(h_(gy, gx - 1) + h_(gy, gx + 1) - 2 * c), ay = std::fabs(h_(gy - 1, gx) + h_(gy + 1, gx) - 2 * c);
        const float m = std::min(std::isnan(ax) ? FLT_MAX : ax, std::isnan(ay) ? FLT_MAX : ay);
        if (m != FLT_MAX) curv.push_back(m);
      }
    float roughness = 0;
    if (!curv.empty()) {
      auto mid = curv.begin() + curv.size() / 2;
      std::nth_element(curv.begin(), mid, curv.end());
      roughness = *mid;
    }
    if (roughness > o_.max_roughness) return false;
    // Counter-clockwise on screen (y down): negative shoelace sum.
    double shoelace = 0;
    for (size_t i = 0, n = contour.size(); i < n; ++i) {
      const cv::Point& a = contour[i];
      const cv::Point& b = contour[(i + 1) % n];
      shoelace += static_cast<double>(a.x) * b.y - static_cast<double>(b.x) * a.y;
    }
    if (shoelace > 0) std::reverse(contour.begin(), contour.end());
    region->contour = std::move(contour);
    region->bbox = cv::boundingRect(region->contour);
    std::vector<float> heights;
    heights.reserve(pixels.size());
    for (int p : pixels) heights.push_back(H(p));
    auto mid = heights.begin() + heights.size() / 2;
    std::nth_element(heights.begin(), mid, heights.end());
    region->height = *mid;
    return true;
  }

  // Several markers on one building give the same region: keep one of those
  // whose bounding-box corners all lie within merge_corner_px and whose areas
  // differ by at most merge_area_ratio.
  std::vector<BuildingRegion> Merge(std::vector<BuildingRegion> regions) const {
    std::stable_sort(regions.begin(), regions.end(), [](const BuildingRegion& a, const BuildingRegion& b) { return a.area > b.area; });
    std::vector<BuildingRegion> kept;
    for (BuildingRegion& r : regions) {
      bool duplicate = false;
      for (const BuildingRegion& k : kept) {
        const double d = std::max({cv::norm(r.bbox.tl() - k.bbox.tl()), cv::norm(r.bbox.br() - k.bbox.br()),
                                   std::hypot(r.bbox.x - k.bbox.x, r.bbox.br().y - k.bbox.br().y),
                                   std::hypot(r.bbox.br().x - k.bbox.br().x, r.bbox.y - k.bbox.y)});
        if (d < o_.merge_corner_px && std::fabs(r.area - k.area) <= o_.merge_area_ratio * std::max(r.area, k.area)) {
          duplicate = true;
          break;
        }
      }
      if (!duplicate) kept.push_back(std::move(r));
    }
    return kept;
  }

  const DepthSegmentOptions& o_;
  const cv::Mat1f& h_;
  const int w_, ht_;
  float wl_low_ = 0;
  std::vector<Offset> offsets_;
  std::vector<uint8_t> lcc_;  // 0 unknown, 1 pass, 2 fail
  std::vector<int> stamp_;    // last region that queued the pixel
  std::vector<uint8_t> covered_;
  int region_id_ = 0;
};

}  // namespace

std::vector<BuildingRegion> SegmentDepth(const cv::Mat1f& depth, const DepthSegmentOptions& options, cv::Mat1i* labels,
                                         cv::Mat1f* above_ground) {
  options.Check();
  Require(!depth.empty(), ErrorCode::kBadImage, "depth segmentation: empty depth image");
  Require(depth.total() < (size_t{1} << 30), ErrorCode::kBadImage,
          "depth segmentation: the depth image is too large (" + std::to_string(depth.cols) + "x" + std::to_string(depth.rows) +
              "); split it into tiles");
  // Normalised heights: no data -> NaN; relative to the local ground.
  cv::Mat1f h(depth.size());
  float lo = FLT_MAX;
  size_t valid = 0;
  for (int y = 0; y < depth.rows; ++y) {
    const float* src = depth[y];
    float* dst = h[y];
    for (int x = 0; x < depth.cols; ++x) {
      const float v = src[x];
      if (std::isfinite(v) && v != options.nodata) {
        dst[x] = v, lo = std::min(lo, v), ++valid;
      } else {
        dst[x] = kNaN;
      }
    }
  }
  Require(valid > 0, ErrorCode::kBadImage,
          "depth segmentation: the " + std::to_string(depth.cols) + "x" + std::to_string(depth.rows) +
              " depth image has no data (all NaN or nodata)");
  if (options.estimate_ground) {
    const cv::Mat1f ground = EstimateGround(h, options.ground_window, lo);
    cv::subtract(h, ground, h);  // NaN stays NaN
  }
  std::vector<BuildingRegion> regions = Segmenter(h, options).Run();
  if (above_ground) *above_ground = h;
  if (labels) {
    *labels = cv::Mat1i::zeros(depth.size());
    for (size_t i = 0; i < regions.size(); ++i)
      cv::drawContours(*labels, std::vector<std::vector<cv::Point>>{regions[i].contour}, 0, cv::Scalar(static_cast<int>(i + 1)),
                       cv::FILLED, cv::LINE_8);
  }
  return regions;
}

void ObjectOutlineOptions::Check() const {
  Require(std::isfinite(min_height) && min_height > 0 && min_area >= 1 && building_margin >= 0, ErrorCode::kInvalidArgument,
          "ObjectOutlineOptions: need min_height > 0, min_area >= 1, building_margin >= 0");
}

std::vector<std::vector<cv::Point>> ObjectOutlines(const cv::Mat1f& above_ground, const std::vector<BuildingRegion>& regions,
                                                   const ObjectOutlineOptions& o) {
  o.Check();
  std::vector<std::vector<cv::Point>> out;
  if (above_ground.empty()) return out;
  cv::Mat1b mask(above_ground.size());
  for (int y = 0; y < above_ground.rows; ++y) {
    const float* h = above_ground[y];
    uint8_t* m = mask[y];
    for (int x = 0; x < above_ground.cols; ++x) m[x] = h[x] >= o.min_height ? 255 : 0;  // false for NaN
  }
  cv::Mat1b built = cv::Mat1b::zeros(above_ground.size());
  for (const auto& r : regions) cv::drawContours(built, std::vector<std::vector<cv::Point>>{r.contour}, 0, cv::Scalar(255), cv::FILLED);
  if (o.building_margin > 0)
    cv::dilate(built, built, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * o.building_margin + 1, 2 * o.building_margin + 1)));
  mask.setTo(0, built);
  cv::Mat1i lab;
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, lab, stats, centroids, 8, CV_32S);
  for (int i = 1; i < n; ++i) {
    if (stats.at<int>(i, cv::CC_STAT_AREA) < o.min_area) continue;
    const cv::Rect b(stats.at<int>(i, cv::CC_STAT_LEFT) - 1, stats.at<int>(i, cv::CC_STAT_TOP) - 1,
                     stats.at<int>(i, cv::CC_STAT_WIDTH) + 2, stats.at<int>(i, cv::CC_STAT_HEIGHT) + 2);
    const cv::Rect in = b & cv::Rect(0, 0, lab.cols, lab.rows);
    cv::Mat1b one = cv::Mat1b::zeros(b.size());
    cv::Mat1b(lab(in) == i).copyTo(one(in - b.tl()));
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(one, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE, b.tl());
    for (auto& c : contours)
      if (c.size() >= 6) out.push_back(std::move(c));
  }
  return out;
}

cv::Mat DrawRegions(const cv::Mat1f& depth, const std::vector<BuildingRegion>& regions) {
  float lo = FLT_MAX, hi = -FLT_MAX;
  for (float v : depth)
    if (std::isfinite(v) && v > -9000.f) lo = std::min(lo, v), hi = std::max(hi, v);
  const float scale = hi > lo ? 215.f / (hi - lo) : 0.f;
  cv::Mat3b out(depth.size());
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      const float v = depth(y, x);
      if (std::isfinite(v) && v > -9000.f) {
        const auto g = static_cast<uint8_t>(40.f + (v - lo) * scale);
        out(y, x) = {g, g, g};
      } else {
        out(y, x) = {0, 0, 96};
      }
    }
  for (size_t i = 0; i < regions.size(); ++i) {
    // Well-spread hues from the golden angle.
    cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<uint8_t>(static_cast<int>(i * 137.508) % 360 / 2), 220, 255));
    cv::Mat3b bgr;
    cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
    const cv::Vec3b c = bgr(0, 0);
    const std::vector<std::vector<cv::Point>> one{regions[i].contour};
    cv::Mat1b mask = cv::Mat1b::zeros(depth.size());
    cv::drawContours(mask, one, 0, 255, cv::FILLED);
    for (int y = regions[i].bbox.y; y < regions[i].bbox.br().y; ++y)
      for (int x = regions[i].bbox.x; x < regions[i].bbox.br().x; ++x)
        if (mask(y, x)) {
          cv::Vec3b& p = out(y, x);
          for (int k = 0; k < 3; ++k) p[k] = static_cast<uint8_t>((p[k] + c[k]) / 2);
        }
    cv::polylines(out, one, true, cv::Scalar(c[0], c[1], c[2]), 1, cv::LINE_8);
  }
  return out;
}

}  // namespace mvkp
