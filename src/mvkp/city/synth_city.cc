#include "mvkp/city/synth_city.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Platform-independent sampling on top of std::mt19937_64 (whose output is
// specified by the standard; the std distributions are not).
struct Rng {
  std::mt19937_64 g;
  explicit Rng(std::uint64_t seed) : g(seed) {}
  double U() { return double(g() >> 11) * 0x1.0p-53; }
  double U(double a, double b) { return a + (b - a) * U(); }
  int I(int a, int b) { return std::min(b, a + int(U() * (b - a + 1))); }  // inclusive
  bool B(double p) { return U() < p; }
  double N() {  // Box-Muller
    double u1 = U();
    while (u1 <= 1e-300) u1 = U();
    return std::sqrt(-2 * std::log(u1)) * std::cos(2 * kPi * U());
  }
  std::uint64_t Next() { return g(); }
  template <class T>
  const T& Pick(const std::vector<T>& v) { return v[size_t(I(0, int(v.size()) - 1))]; }
};

std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
double Hash01(std::uint64_t key, long a, long b) {
  return double(SplitMix(key ^ SplitMix(std::uint64_t(a) * 0x100000001b3ull + std::uint64_t(b) * 0x51ed27ull)) >> 11) *
         0x1.0p-53;
}

// A raster over the world (world units = depth pixels, pixel centres at integers).
// Pixel u of the grid has its centre at world x = x0 + (u + 0.5) / f.
struct Grid {
  double x0 = -0.5, y0 = -0.5, f = 1;
  int w = 0, h = 0;
  cv::Point2d ToPix(cv::Point2d p) const { return {f * (p.x - x0) - 0.5, f * (p.y - y0) - 0.5}; }
  cv::Point2d ToWorld(double u, double v) const { return {x0 + (u + 0.5) / f, y0 + (v + 0.5) / f}; }
  cv::Matx33d WorldToPix() const { return {f, 0, -f * x0 - 0.5, 0, f, -f * y0 - 0.5, 0, 0, 1}; }
};

Grid GridOver(const cv::Rect2d& world, double f) {
  Grid g;
  g.x0 = std::floor(world.x) - 0.5;
  g.y0 = std::floor(world.y) - 0.5;
  g.f = f;
  g.w = std::max(1, int(std::ceil((world.x + world.width - g.x0) * f)));
  g.h = std::max(1, int(std::ceil((world.y + world.height - g.y0) * f)));
  return g;
}

// ----------------------------------------------------------------------------
// Road grid: two families of parallel roads at angle alpha, jittered spacing,
// main and minor roads. Queried analytically per pixel.
struct RoadQuery {
  double m[2];       // signed distance to the nearest road centre line of each family (metres)
  double hw[2];      // half width of that road (metres)
  double along[2];   // coordinate along that road (metres)
  bool main[2];
  long block[2];     // block index between roads
};

struct Layout {
  double alpha = 0, ca = 1, sa = 0, res = 0.5;
  double spacing[2] = {120, 120};
  std::uint64_t key = 0;
  double sidewalk = 2.5;
  double Centre(int fam, long k) const { return k * spacing[fam] + (Hash01(key, fam * 7 + 1, k) - 0.5) * 0.3 * spacing[fam]; }
  bool Main(int fam, long k) const { return Hash01(key, fam * 7 + 2, k) < 0.3; }
  double HalfWidth(int fam, long k) const {
    const double r = Hash01(key, fam * 7 + 3, k);
    return Main(fam, k) ? 8 + 2 * r : 4.5 + 2 * r;
  }
  RoadQuery Query(double x, double y) const {  // world (depth pixel) coordinates
    const double X = x * res, Y = y * res;
    const double t[2] = {X * ca + Y * sa, -X * sa + Y * ca};
    RoadQuery q;
    for (int fam = 0; fam < 2; ++fam) {
      const long k0 = long(std::floor(t[fam] / spacing[fam]));
      double best = 1e18;
      long bk = k0;
      for (long k = k0 - 1; k <= k0 + 1; ++k) {
        const double d = t[fam] - Centre(fam, k);
        if (std::abs(d) < std::abs(best)) best = d, bk = k;
      }
      q.m[fam] = best;
      q.hw[fam] = HalfWidth(fam, bk);
      q.main[fam] = Main(fam, bk);
      q.along[fam] = t[1 - fam];
      q.block[fam] = best >= 0 ? bk : bk - 1;
    }
    return q;
  }
  // Unit vector (world) across roads of family fam (direction of increasing t[fam]).
  cv::Point2d Across(int fam) const { return fam == 0 ? cv::Point2d(ca, sa) : cv::Point2d(-sa, ca); }
};

// The street layout: one grid, or (styles other than classic) a second, rotated grid
// on the far side of a straight line.
struct Streets : Layout {
  std::vector<Layout> alt;  // 0 or 1
  cv::Point2d split_n{1, 0};
  double split_d = 0;
  const Layout& At(double x, double y) const {
    return !alt.empty() && x * split_n.x + y * split_n.y > split_d ? alt[0] : *this;
  }
  RoadQuery Query(double x, double y) const { return At(x, y).Layout::Query(x, y); }
  cv::Point2d AcrossAt(int fam, cv::Point2d p) const { return At(p.x, p.y).Across(fam); }
  double AlphaAt(cv::Point2d p) const { return At(p.x, p.y).alpha; }
};

bool OnRoad(const RoadQuery& q, double extra = 0) {
  return std::abs(q.m[0]) < q.hw[0] + extra || std::abs(q.m[1]) < q.hw[1] + extra;
}

// ----------------------------------------------------------------------------
struct RoofBox {
  std::vector<cv::Point2d> poly;  // world
  double h_m;
};

struct Building {
  std::vector<cv::Point2d> outer;               // world (depth pixels)
  std::vector<std::vector<cv::Point2d>> holes;  // world
  std::string shape;
  double eave_m = 5;
  RoofType roof = RoofType::kFlat;
  double pitch = 0.6;                           // tan of roof pitch
  cv::Point2d centre, short_axis;               // gable: ridge through centre, across = short_axis (unit)
  double half_short_m = 5;
  int material = 0;                             // 0 gravel 1 membrane 2 tar 3 green | 10 tiles 11 metal
  cv::Vec3b colour;
  std::vector<RoofBox> boxes;
  double nodata = 0;                            // styles: share of roof pixels without a LiDAR return
  cv::Vec3b wall{170, 172, 175};                // styles: facade colour (lean)
};

struct Tree {
  cv::Point2d c;   // world
  double r_m, h_m;
  cv::Vec3b colour;
  double lobes[4];  // crown outline irregularity
};

struct Car {
  std::vector<cv::Point2d> poly;  // world, 4 corners, front first two
  cv::Vec3b colour;
};

enum class Style { kClassic = 0, kSuburb = 1, kDense = 2, kCivic = 3 };

// Ground patches of the styles other than classic.
struct Patch {
  enum Kind { kCoping = 0, kWater = 1, kHedge = 2 } kind;
  std::vector<cv::Point2d> poly;  // world
  double h_m = 0;                 // hedge height
};

// A parking lot: a rectangle with rows of stalls across axis v.
struct Lot {
  std::vector<cv::Point2d> poly;  // world
  cv::Point2d origin, u, v;       // world origin (a corner) and unit axes (world)
  double w_m = 0, d_m = 0;
};

struct Scene {
  Streets lay;
  Style style = Style::kClassic;
  std::vector<Patch> patches;
  std::vector<Lot> lots;
  int first_minor = 1 << 30;  // s.b[first_minor..]: sheds, never counted
  cv::Point2d lean_px{0, 0};  // photo displacement per metre of height (world px), styles only
  std::vector<Building> b;  // counted ones first
  int counted = 0;
  std::vector<Tree> t;
  std::vector<Car> cars;
  double res = 0.5;
  double sun_az = 0, sun_el = 45;
  std::uint64_t tex_seed = 0;
};

std::vector<cv::Point> ToFixed(const std::vector<cv::Point2d>& world, const Grid& g, cv::Point2d off) {
  std::vector<cv::Point> out;
  out.reserve(world.size());
  for (const auto& p : world) {
    const cv::Point2d q = g.ToPix(p) - off;
    out.emplace_back(int(std::lround(q.x * 256)), int(std::lround(q.y * 256)));
  }
  return out;
}

cv::Rect PixBox(const std::vector<cv::Point2d>& world, const Grid& g, int pad) {
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const auto& p : world) {
    const cv::Point2d q = g.ToPix(p);
    x0 = std::min(x0, q.x), y0 = std::min(y0, q.y), x1 = std::max(x1, q.x), y1 = std::max(y1, q.y);
  }
  cv::Rect r(int(std::floor(x0)) - pad, int(std::floor(y0)) - pad, 0, 0);
  r.width = int(std::ceil(x1)) + pad + 1 - r.x;
  r.height = int(std::ceil(y1)) + pad + 1 - r.y;
  return r;
}

// Mask of the polygon (outer minus holes) over `box` (grid pixels, may extend beyond the grid).
cv::Mat1b PolyMask(const std::vector<cv::Point2d>& outer, const std::vector<std::vector<cv::Point2d>>& holes,
                   const Grid& g, const cv::Rect& box) {
  cv::Mat1b m(box.size(), uchar(0));
  const cv::Point2d off(box.x, box.y);
  std::vector<std::vector<cv::Point>> o{ToFixed(outer, g, off)};
  cv::fillPoly(m, o, cv::Scalar(255), cv::LINE_8, 8);
  for (const auto& h : holes) {
    std::vector<std::vector<cv::Point>> hh{ToFixed(h, g, off)};
    cv::fillPoly(m, hh, cv::Scalar(0), cv::LINE_8, 8);
  }
  return m;
}

// ----------------------------------------------------------------------------
// Heights (nDSM), classes and surface slopes rendered on a grid.
enum Cls : uchar { kGround = 0, kRoof = 1, kRoofBox = 2, kTree = 3, kCar = 4, kWater = 5, kHedge = 6, kCoping = 7 };

struct Raster {
  cv::Mat1f h;       // metres above ground
  cv::Mat1i id;      // scene building index or -1
  cv::Mat1b cls;
  cv::Mat1f roof;    // roof rise above eave (metres), for tile rows
  cv::Mat1f gx, gy;  // surface slope dh/dx, dh/dy (metres per metre)
  cv::Mat1f tree_r;  // relative radius inside a crown (for texture), 0 elsewhere
  cv::Mat1i tree_i;  // tree index or -1
  cv::Mat1f edge;    // distance to the roof outline (metres), roofs only
};

// noisy_trees: LiDAR-like canopy (per-pixel random penetration) instead of a smooth dome.
Raster RenderHeights(const Scene& s, const Grid& g, bool slopes, bool noisy_trees, std::uint64_t noise_seed) {
  Raster r;
  r.h = cv::Mat1f(g.h, g.w, 0.f);
  r.id = cv::Mat1i(g.h, g.w, -1);
  r.cls = cv::Mat1b(g.h, g.w, uchar(kGround));
  if (slopes) {
    r.roof = cv::Mat1f(g.h, g.w, 0.f);
    r.gx = cv::Mat1f(g.h, g.w, 0.f);
    r.gy = cv::Mat1f(g.h, g.w, 0.f);
    r.tree_r = cv::Mat1f(g.h, g.w, 0.f);
    r.tree_i = cv::Mat1i(g.h, g.w, -1);
    r.edge = cv::Mat1f(g.h, g.w, 0.f);
  }
  const cv::Rect all(0, 0, g.w, g.h);
  const double px_m = s.res / g.f;  // grid pixel size in metres
  for (int bi = 0; bi < int(s.b.size()); ++bi) {
    const Building& b = s.b[bi];
    const cv::Rect box = PixBox(b.outer, g, 3);
    const cv::Rect clip = box & all;
    if (clip.empty()) continue;
    const cv::Mat1b m = PolyMask(b.outer, b.holes, g, box);
    cv::Mat1f R(box.size(), 0.f), GX, GY, D;
    if (slopes || b.roof == RoofType::kHip || b.roof == RoofType::kDome)
      cv::distanceTransform(m, D, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    if (b.roof == RoofType::kHip || b.roof == RoofType::kDome) {
      for (int y = 0; y < D.rows; ++y)
        for (int x = 0; x < D.cols; ++x) {
          if (!m(y, x)) continue;
          const double d = std::max(0.0, (D(y, x) - 0.5) * px_m);
          if (b.roof == RoofType::kHip) {
            R(y, x) = float(d * b.pitch);
          } else {  // dome: radius half_short_m, rise pitch (metres)
            const double q = 1 - std::min(1.0, d / b.half_short_m);
            R(y, x) = float(b.pitch * std::sqrt(std::max(0.0, 1 - q * q)));
          }
        }
      if (slopes) {
        cv::Sobel(R, GX, CV_32F, 1, 0, 3, 1.0 / (8 * px_m));
        cv::Sobel(R, GY, CV_32F, 0, 1, 3, 1.0 / (8 * px_m));
      }
    } else if (b.roof == RoofType::kGable) {
      GX = cv::Mat1f(box.size(), 0.f), GY = cv::Mat1f(box.size(), 0.f);
      for (int y = 0; y < R.rows; ++y)
        for (int x = 0; x < R.cols; ++x) {
          if (!m(y, x)) continue;
          const cv::Point2d w = g.ToWorld(box.x + x, box.y + y) - b.centre;
          const double v = (w.x * b.short_axis.x + w.y * b.short_axis.y) * s.res;
          R(y, x) = float(std::max(0.0, b.half_short_m - std::abs(v)) * b.pitch);
          const double sg = v >= 0 ? -b.pitch : b.pitch;
          GX(y, x) = float(sg * b.short_axis.x);
          GY(y, x) = float(sg * b.short_axis.y);
        }
    } else if (b.roof == RoofType::kShed) {  // one plane, rising along short_axis
      GX = cv::Mat1f(box.size(), 0.f), GY = cv::Mat1f(box.size(), 0.f);
      for (int y = 0; y < R.rows; ++y)
        for (int x = 0; x < R.cols; ++x) {
          if (!m(y, x)) continue;
          const cv::Point2d w = g.ToWorld(box.x + x, box.y + y) - b.centre;
          const double v = (w.x * b.short_axis.x + w.y * b.short_axis.y) * s.res;
          R(y, x) = float(std::clamp(b.half_short_m + v, 0.0, 2 * b.half_short_m) * b.pitch);
          GX(y, x) = float(b.pitch * b.short_axis.x);
          GY(y, x) = float(b.pitch * b.short_axis.y);
        }
    }
    for (int y = clip.y; y < clip.y + clip.height; ++y)
      for (int x = clip.x; x < clip.x + clip.width; ++x) {
        const int ly = y - box.y, lx = x - box.x;
        if (!m(ly, lx)) continue;
        r.h(y, x) = float(b.eave_m + R(ly, lx));
        r.id(y, x) = bi;
        r.cls(y, x) = kRoof;
        if (slopes) {
          r.roof(y, x) = R(ly, lx);
          r.edge(y, x) = float((D(ly, lx) - 0.5) * px_m);
          if (!GX.empty()) r.gx(y, x) = GX(ly, lx), r.gy(y, x) = GY(ly, lx);
        }
      }
    for (const RoofBox& rb : b.boxes) {
      const cv::Rect bb = PixBox(rb.poly, g, 1);
      const cv::Rect bc = bb & all;
      if (bc.empty()) continue;
      const cv::Mat1b bm = PolyMask(rb.poly, {}, g, bb);
      for (int y = bc.y; y < bc.y + bc.height; ++y)
        for (int x = bc.x; x < bc.x + bc.width; ++x)
          if (bm(y - bb.y, x - bb.x) && r.id(y, x) == bi) {
            r.h(y, x) = float(b.eave_m + rb.h_m);
            r.cls(y, x) = kRoofBox;
          }
    }
  }
  Rng nr(noise_seed);
  for (const Patch& p : s.patches) {  // pools and hedges, on the ground only
    const cv::Rect bb = PixBox(p.poly, g, 1);
    const cv::Rect bc = bb & all;
    if (bc.empty()) continue;
    const cv::Mat1b bm = PolyMask(p.poly, {}, g, bb);
    for (int y = bc.y; y < bc.y + bc.height; ++y)
      for (int x = bc.x; x < bc.x + bc.width; ++x) {
        if (!bm(y - bb.y, x - bb.x)) continue;
        const uchar c = r.cls(y, x);
        if (p.kind == Patch::kHedge) {
          if (c != kGround) continue;
          double h = p.h_m;
          if (noisy_trees) h *= nr.U(0.8, 1.0);
          r.h(y, x) = float(h), r.cls(y, x) = kHedge;
        } else if (c == kGround || c == kCoping || c == kWater) {
          r.cls(y, x) = p.kind == Patch::kWater ? kWater : kCoping;
        }
      }
  }
  for (const Car& c : s.cars) {
    const cv::Rect bb = PixBox(c.poly, g, 1);
    const cv::Rect bc = bb & all;
    if (bc.empty()) continue;
    const cv::Mat1b bm = PolyMask(c.poly, {}, g, bb);
    for (int y = bc.y; y < bc.y + bc.height; ++y)
      for (int x = bc.x; x < bc.x + bc.width; ++x)
        if (bm(y - bb.y, x - bb.x) && r.cls(y, x) == kGround) r.h(y, x) = 1.5f, r.cls(y, x) = kCar;
  }
  for (int ti = 0; ti < int(s.t.size()); ++ti) {
    const Tree& t = s.t[ti];
    const double rpx = t.r_m / s.res * 1.25;  // world px, with the lobes
    const cv::Rect bb = PixBox({t.c - cv::Point2d(rpx, rpx), t.c + cv::Point2d(rpx, rpx)}, g, 1);
    const cv::Rect bc = bb & all;
    for (int y = bc.y; y < bc.y + bc.height; ++y)
      for (int x = bc.x; x < bc.x + bc.width; ++x) {
        const cv::Point2d d = (g.ToWorld(x, y) - t.c) * s.res;  // metres
        const double rr = std::hypot(d.x, d.y), th = std::atan2(d.y, d.x);
        const double R = t.r_m * (1 + 0.12 * std::sin(3 * th + t.lobes[0]) + 0.08 * std::sin(5 * th + t.lobes[1]) +
                                  0.05 * std::sin(7 * th + t.lobes[2]));
        if (rr >= R) continue;
        const double q = rr / R, dome = std::sqrt(std::max(0.0, 1 - q * q));
        double h = t.h_m * (0.55 + 0.45 * dome);
        if (noisy_trees) {
          if (nr.B(0.15 + 0.2 * q)) continue;  // a return from the ground below the canopy
          h *= nr.U(0.6, 1.0);
          h += 0.4 * nr.N();
        }
        if (h <= r.h(y, x)) continue;
        r.h(y, x) = float(h);
        r.cls(y, x) = kTree;
        if (slopes) {
          const double dd = std::max(dome, 0.25);
          const double dh = -t.h_m * 0.45 * q / dd / R;  // dh/dr
          r.gx(y, x) = float(rr > 1e-9 ? dh * d.x / rr : 0);
          r.gy(y, x) = float(rr > 1e-9 ? dh * d.y / rr : 0);
          r.tree_r(y, x) = float(q);
          r.tree_i(y, x) = ti;
          r.id(y, x) = -1;
        }
      }
  }
  return r;
}

// ----------------------------------------------------------------------------
// Footprint shapes in local metres, centred at the origin.
std::vector<cv::Point2d> RectPts(double w, double h) {
  return {{-w / 2, -h / 2}, {w / 2, -h / 2}, {w / 2, h / 2}, {-w / 2, h / 2}};
}
void Centre(std::vector<cv::Point2d>& p, double w, double h) {
  for (auto& q : p) q -= cv::Point2d(w / 2, h / 2);
}

struct LocalShape {
  std::vector<cv::Point2d> outer;
  std::vector<std::vector<cv::Point2d>> holes;
  std::string name;
};

LocalShape MakeShape(Rng& r, double w, double h, bool allow_courtyard) {
  LocalShape s;
  double p = r.U();
  if (!allow_courtyard && p >= 0.64 && p < 0.74) p = r.U(0, 0.64);
  if (p < 0.3) {
    s.name = "rect";
    s.outer = RectPts(w, h);
  } else if (p < 0.46) {  // L: cut one corner
    s.name = "L";
    const double a = w * r.U(0.35, 0.6), b = h * r.U(0.35, 0.6);
    s.outer = {{0, 0}, {w - a, 0}, {w - a, b}, {w, b}, {w, h}, {0, h}};
    Centre(s.outer, w, h);
  } else if (p < 0.56) {  // T
    s.name = "T";
    const double t = h * r.U(0.3, 0.5), sw = w * r.U(0.3, 0.5), x1 = r.U(0.15 * w, 0.85 * w - sw);
    s.outer = {{0, 0}, {w, 0}, {w, t}, {x1 + sw, t}, {x1 + sw, h}, {x1, h}, {x1, t}, {0, t}};
    Centre(s.outer, w, h);
  } else if (p < 0.64) {  // U
    s.name = "U";
    const double n = w * r.U(0.3, 0.5), d = h * r.U(0.4, 0.7), x1 = (w - n) / 2 + r.U(-0.1, 0.1) * w;
    s.outer = {{0, 0}, {x1, 0}, {x1, d}, {x1 + n, d}, {x1 + n, 0}, {w, 0}, {w, h}, {0, h}};
    Centre(s.outer, w, h);
  } else if (p < 0.74) {  // courtyard
    s.name = "courtyard";
    s.outer = RectPts(w, h);
    const double t = std::min({r.U(7, 13), w / 3, h / 3});
    s.holes.push_back({{-w / 2 + t, -h / 2 + t}, {-w / 2 + t, h / 2 - t}, {w / 2 - t, h / 2 - t}, {w / 2 - t, -h / 2 + t}});
  } else {  // irregular: rectangle with chamfered or notched corners
    s.name = "irregular";
    const std::vector<cv::Point2d> c = RectPts(w, h);
    int changed = 0;
    for (int i = 0; i < 4; ++i) {
      const cv::Point2d C = c[size_t(i)], P = c[size_t((i + 3) % 4)], N = c[size_t((i + 1) % 4)];
      const cv::Point2d a = (P - C) / cv::norm(P - C), bdir = (N - C) / cv::norm(N - C);
      const double m = std::min(w, h);
      const double kind = r.U();
      if (kind < 0.3 || (i == 3 && changed == 0)) {
        const double sz = m * r.U(0.15, 0.35);
        s.outer.push_back(C + a * sz);
        s.outer.push_back(C + bdir * sz);
        ++changed;
      } else if (kind < 0.6) {
        const double s1 = m * r.U(0.15, 0.35), s2 = m * r.U(0.15, 0.35);
        s.outer.push_back(C + a * s1);
        s.outer.push_back(C + a * s1 + bdir * s2);
        s.outer.push_back(C + bdir * s2);
        ++changed;
      } else {
        s.outer.push_back(C);
      }
    }
  }
  return s;
}

cv::Vec3b Jitter(Rng& r, cv::Vec3b c, double amount) {
  const double g = r.U(1 - amount, 1 + amount);
  cv::Vec3b o;
  for (int k = 0; k < 3; ++k) o[k] = cv::saturate_cast<uchar>(c[k] * g * r.U(0.96, 1.04));
  return o;
}

void PickRoofMaterial(Rng& r, Building& b) {
  if (b.roof == RoofType::kFlat) {
    const double p = r.U();
    if (p < 0.4) {
      b.material = 0;
      b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{150, 155, 160}, {128, 138, 150}, {140, 140, 135}}), 0.12);
    } else if (p < 0.75) {
      b.material = 1;
      b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{205, 208, 210}, {220, 220, 222}, {185, 190, 192}}), 0.06);
    } else if (p < 0.93) {
      b.material = 2;
      b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{72, 72, 76}, {60, 66, 72}, {88, 84, 80}}), 0.12);
    } else {
      b.material = 3;
      b.colour = Jitter(r, cv::Vec3b(70, 125, 95), 0.1);
    }
  } else {
    if (r.B(0.75)) {
      b.material = 10;
      b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{55, 75, 160}, {50, 62, 125}, {72, 75, 82}, {45, 55, 95}}), 0.1);
    } else {
      b.material = 11;
      b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{165, 160, 150}, {125, 95, 60}, {70, 95, 70}}), 0.08);
    }
  }
}

// ----------------------------------------------------------------------------
// Placement on a world occupancy raster (f = 1): 1 road/sidewalk, 2 building or
// its clearance; zone: 1 inside the depth raster, 2 outside it, 0 the border.
struct Placer {
  Grid g;
  cv::Mat1b occ, zone;
};

bool TryPlace(Placer& P, const std::vector<cv::Point2d>& outer, int want_zone, double gap_px) {
  const cv::Rect box = PixBox(outer, P.g, 2);
  if ((box & cv::Rect(0, 0, P.g.w, P.g.h)) != box) return false;
  const cv::Mat1b m = PolyMask(outer, {}, P.g, box);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      if (m(y, x) && (P.occ(box.y + y, box.x + x) || P.zone(box.y + y, box.x + x) != want_zone)) return false;
  std::vector<std::vector<cv::Point>> o{ToFixed(outer, P.g, {0, 0})};
  cv::fillPoly(P.occ, o, cv::Scalar(2), cv::LINE_8, 8);
  cv::polylines(P.occ, o, true, cv::Scalar(2), std::max(1, int(std::lround(2 * gap_px))), cv::LINE_8, 8);
  return true;
}

Building MakeBuilding(Rng& r, const Scene& s, cv::Point2d centre_world, bool pitched_ok) {
  Building b;
  const double cls = r.U();
  double w, h;
  if (cls < 0.45) {  // residential
    w = r.U(9, 20), h = r.U(9, 26);
    b.eave_m = r.U(3, 10);
  } else if (cls < 0.85) {  // commercial
    w = r.U(18, 55), h = r.U(18, 60);
    b.eave_m = r.U(6, 25);
  } else {  // large / tower
    w = r.U(25, 70), h = r.U(25, 70);
    b.eave_m = r.U(18, 40);
  }
  const LocalShape ls = MakeShape(r, w, h, std::min(w, h) >= 32);
  b.shape = ls.name;
  double ang = s.lay.alpha + r.I(0, 3) * kPi / 2;
  if (r.B(0.15)) ang = r.U(0, 2 * kPi);  // rotated off the grid
  else ang += r.U(-0.03, 0.03);
  const double c = std::cos(ang), sn = std::sin(ang);
  auto place = [&](const std::vector<cv::Point2d>& v) {
    std::vector<cv::Point2d> o;
    for (const auto& p : v) o.push_back(centre_world + cv::Point2d(p.x * c - p.y * sn, p.x * sn + p.y * c) / s.res);
    return o;
  };
  b.outer = place(ls.outer);
  for (const auto& hole : ls.holes) b.holes.push_back(place(hole));
  b.centre = centre_world;
  const bool small = std::min(w, h) <= 24;
  if (pitched_ok && small && cls < 0.6 && b.holes.empty() && r.B(0.75)) {
    b.pitch = std::tan(r.U(22, 40) * kPi / 180);
    b.roof = (b.shape == "rect" && r.B(0.6)) ? RoofType::kGable : RoofType::kHip;
    b.eave_m = std::min(b.eave_m, 10.0);
    if (b.roof == RoofType::kGable) {
      // Ridge along the long side.
      const cv::Point2d ax = w < h ? cv::Point2d(c, sn) : cv::Point2d(-sn, c);
      b.short_axis = ax;
      b.half_short_m = std::min(w, h) / 2;
    }
  }
  PickRoofMaterial(r, b);
  if (b.roof == RoofType::kFlat && w * h > 500) {
    const int n = r.I(0, 4);
    for (int i = 0; i < n; ++i) {
      const double bw = r.U(1.5, 5), bh = r.U(1.5, 5);
      const cv::Point2d at(r.U(-w / 2 + bw, w / 2 - bw), r.U(-h / 2 + bh, h / 2 - bh));
      std::vector<cv::Point2d> pts = RectPts(bw, bh);
      for (auto& p : pts) p += at;
      const std::vector<cv::Point2d> world = place(pts);
      bool inside = true;
      std::vector<cv::Point2f> outer_f(b.outer.begin(), b.outer.end());
      for (const auto& p : world) inside &= cv::pointPolygonTest(outer_f, cv::Point2f(p), true) > 1.0;
      for (const auto& hole : b.holes) {
        std::vector<cv::Point2f> hf(hole.begin(), hole.end());
        for (const auto& p : world) inside &= cv::pointPolygonTest(hf, cv::Point2f(p), true) < -1.0;
      }
      if (inside) b.boxes.push_back({world, r.U(1, 3)});
    }
  }
  return b;
}

// ----------------------------------------------------------------------------
// Buildings of the styles other than classic. `kind` tells what goes around them:
// "house" (a garden), "hall" (a parking lot) or "".
Building MakeStyledBuilding(Rng& r, const Scene& s, cv::Point2d centre_world, Style style, bool pitched_ok,
                            std::string* kind) {
  Building b;
  kind->clear();
  double w = 10, h = 10;
  LocalShape ls;
  enum { kHouse, kBar, kBlock, kHall, kTower, kRound, kStar } k = kHouse;
  const double p = r.U();
  if (style == Style::kSuburb) {
    k = p < 0.9 ? kHouse : kBlock;
  } else if (style == Style::kDense) {
    k = p < 0.35 ? kBar : p < 0.65 ? kBlock : p < 0.88 ? kHall : kTower;
  } else {  // civic
    k = p < 0.22 ? kRound : p < 0.4 ? kStar : p < 0.7 ? kHouse : p < 0.82 ? kBar : p < 0.92 ? kBlock : kHall;
  }
  switch (k) {
    case kHouse:
      w = r.U(7.5, 13), h = r.U(9, 16);
      b.eave_m = r.U(2.8, 6.5);
      ls = r.B(0.7) ? LocalShape{RectPts(w, h), {}, "rect"} : MakeShape(r, w, h, false);
      if (ls.name == "irregular" || ls.name == "courtyard") ls = LocalShape{RectPts(w, h), {}, "rect"};
      *kind = "house";
      break;
    case kBar:
      w = r.U(10, 15), h = r.U(30, 80);
      b.eave_m = r.U(10, 28);
      ls = LocalShape{RectPts(w, h), {}, "rect"};
      break;
    case kBlock:
      w = r.U(24, 50), h = r.U(24, 55);
      b.eave_m = r.U(9, 24);
      ls = MakeShape(r, w, h, std::min(w, h) >= 30);
      if (ls.name == "rect" || ls.name == "irregular") ls = MakeShape(r, w, h, std::min(w, h) >= 30);
      break;
    case kHall:
      w = r.U(35, 75), h = r.U(25, 50);
      b.eave_m = r.U(6, 11);
      ls = LocalShape{RectPts(w, h), {}, "rect"};
      *kind = "hall";
      break;
    case kTower:
      w = r.U(18, 32), h = r.U(18, 32);
      b.eave_m = r.U(25, 40);
      ls = r.B(0.5) ? LocalShape{RectPts(w, h), {}, "rect"} : MakeShape(r, w, h, false);
      break;
    case kRound: {
      const double rad = r.U(7, 22);
      w = h = 2 * rad;
      b.eave_m = r.U(6, 18);
      ls.name = "round";
      const int n = 48;
      for (int i = 0; i < n; ++i) ls.outer.push_back(cv::Point2d(std::cos(2 * kPi * i / n), std::sin(2 * kPi * i / n)) * rad);
      break;
    }
    case kStar: {
      const double R = r.U(12, 26), q = r.U(0.45, 0.65);
      const int n = r.I(5, 8);
      w = h = 2 * R;
      b.eave_m = r.U(8, 20);
      ls.name = "star";
      for (int i = 0; i < 2 * n; ++i) {
        const double a = kPi * i / n, rr = i % 2 ? R * q : R;
        ls.outer.push_back(cv::Point2d(std::cos(a), std::sin(a)) * rr);
      }
      break;
    }
  }
  b.shape = ls.name;
  double ang = s.lay.AlphaAt(centre_world) + r.I(0, 3) * kPi / 2 + r.U(-0.02, 0.02);
  if (k == kRound || k == kStar || r.B(0.08)) ang = r.U(0, 2 * kPi);
  const double c = std::cos(ang), sn = std::sin(ang);
  auto place = [&](const std::vector<cv::Point2d>& v) {
    std::vector<cv::Point2d> o;
    for (const auto& pt : v) o.push_back(centre_world + cv::Point2d(pt.x * c - pt.y * sn, pt.x * sn + pt.y * c) / s.res);
    return o;
  };
  b.outer = place(ls.outer);
  for (const auto& hole : ls.holes) b.holes.push_back(place(hole));
  b.centre = centre_world;
  const cv::Point2d ax = w < h ? cv::Point2d(c, sn) : cv::Point2d(-sn, c);  // across the long side
  if (k == kRound) {
    b.half_short_m = w / 2;
    if (r.B(0.75)) b.roof = RoofType::kDome, b.pitch = b.half_short_m * r.U(0.3, 0.7);
  } else if (k == kHouse && pitched_ok) {
    const double pr = r.U();
    b.roof = pr < 0.4 && ls.name == "rect" ? RoofType::kGable : pr < 0.75 ? RoofType::kHip : pr < 0.9 ? RoofType::kShed
                                                                                                   : RoofType::kFlat;
    b.short_axis = ax * (r.B(0.5) ? 1.0 : -1.0);
    b.half_short_m = std::min(w, h) / 2;
    b.pitch = std::tan((b.roof == RoofType::kShed ? r.U(8, 18) : r.U(25, 45)) * kPi / 180);
  }
  PickRoofMaterial(r, b);
  if (b.roof == RoofType::kDome) b.material = 11, b.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{120, 130, 90}, {150, 150, 145}, {90, 120, 160}}), 0.08);
  if (k == kHall) b.material = r.B(0.6) ? 1 : 0, b.colour = Jitter(r, b.material == 1 ? cv::Vec3b(212, 214, 216) : cv::Vec3b(150, 152, 155), 0.06);
  if (b.material == 2 && style != Style::kSuburb && r.B(0.7)) b.nodata = r.U(0.4, 0.95);  // dark roof, few returns
  b.wall = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{170, 172, 175}, {150, 175, 195}, {120, 130, 140}, {185, 195, 205}}), 0.08);
  if (b.roof == RoofType::kFlat && w * h > 400 && k != kRound) {
    const int n = k == kHall ? r.I(2, 8) : r.I(1, 5);
    std::vector<cv::Point2f> outer_f(b.outer.begin(), b.outer.end());
    for (int i = 0; i < n; ++i) {
      const double bw = r.U(1.5, 5), bh = r.U(1.5, 5);
      const cv::Point2d at(r.U(-w / 2 + bw, w / 2 - bw), r.U(-h / 2 + bh, h / 2 - bh));
      std::vector<cv::Point2d> pts = RectPts(bw, bh);
      for (auto& pt : pts) pt += at;
      const std::vector<cv::Point2d> world = place(pts);
      bool inside = true;
      for (const auto& pt : world) inside &= cv::pointPolygonTest(outer_f, cv::Point2f(pt), true) > 1.0;
      for (const auto& hole : b.holes) {
        std::vector<cv::Point2f> hf(hole.begin(), hole.end());
        for (const auto& pt : world) inside &= cv::pointPolygonTest(hf, cv::Point2f(pt), true) < -1.0;
      }
      if (inside) b.boxes.push_back({world, r.U(1, 3)});
    }
  }
  return b;
}

void Shift(Building& b, cv::Point2d d) {
  for (auto& p : b.outer) p += d;
  for (auto& h : b.holes) for (auto& p : h) p += d;
  for (auto& bx : b.boxes) for (auto& p : bx.poly) p += d;
  b.centre += d;
}

// Moves a building across the nearest road's direction so that it faces the street
// with a small setback.
void FaceStreet(Rng& r, const Streets& L, Building& b) {
  const RoadQuery q = L.Query(b.centre.x, b.centre.y);
  const int fam = std::abs(q.m[0]) - q.hw[0] < std::abs(q.m[1]) - q.hw[1] ? 0 : 1;
  const cv::Point2d a = L.AcrossAt(fam, b.centre);
  double lo = 1e18, hi = -1e18;
  for (const auto& p : b.outer) {
    const double t = (p - b.centre).dot(a) * L.res;
    lo = std::min(lo, t), hi = std::max(hi, t);
  }
  const double keep = q.hw[fam] + L.sidewalk + r.U(2.5, 8);
  const double shift = q.m[fam] >= 0 ? keep - lo - q.m[fam] : -keep - hi - q.m[fam];
  Shift(b, a * (shift / L.res));
}

// ----------------------------------------------------------------------------
// Value noise in [0, 1] over `size` with features of `cell` pixels.
cv::Mat1f ValueNoise(cv::Size size, double cell, cv::RNG& rng) {
  const int gw = std::max(2, int(size.width / cell) + 3), gh = std::max(2, int(size.height / cell) + 3);
  cv::Mat1f small(gh, gw);
  rng.fill(small, cv::RNG::UNIFORM, 0.f, 1.f);
  cv::Mat1f big;
  cv::resize(small, big, cv::Size(int(gw * cell), int(gh * cell)), 0, 0, cv::INTER_CUBIC);
  return big(cv::Rect(int(cell), int(cell), size.width, size.height)).clone();
}

// Max over the march towards the sun of (height - drop): a pixel is shadowed where
// this exceeds its own height.
cv::Mat1f OccluderField(const cv::Mat1f& h, double res_m, double az_deg, double el_deg) {
  cv::Mat1f M(h.size(), -1e6f);
  const double az = az_deg * kPi / 180, te = std::tan(el_deg * kPi / 180);
  const double sx = std::sin(az), sy = -std::cos(az);
  double hmax = 0;
  cv::minMaxLoc(h, nullptr, &hmax);
  const int K = int(std::ceil(hmax / te / res_m)) + 2;
  int lx = 0, ly = 0;
  for (int k = 1; k <= K; ++k) {
    const int dx = int(std::lround(k * sx)), dy = int(std::lround(k * sy));
    if (k > 1 && dx == lx && dy == ly) continue;
    lx = dx, ly = dy;
    const double dist = std::hypot(dx, dy) * res_m;
    // M(p) = max(M(p), h(p + d) - dist * te)
    const int w = h.cols - std::abs(dx), hh = h.rows - std::abs(dy);
    if (w <= 0 || hh <= 0) break;
    const cv::Rect dst(std::max(0, -dx), std::max(0, -dy), w, hh), src(std::max(0, dx), std::max(0, dy), w, hh);
    cv::Mat1f tmp;
    cv::subtract(h(src), cv::Scalar(dist * te), tmp);
    cv::Mat d = M(dst);
    cv::max(d, cv::Mat(tmp), d);
  }
  return M;
}

inline uchar Sat(double v) { return cv::saturate_cast<uchar>(v); }

void ApplyLean(const Scene& s, const Grid& g, const Raster& r, cv::Mat3b& img, cv::Mat1i* ids);

// True orthophoto of the ground covered by grid g (conventional, leaning, for the
// styles other than classic).
cv::Mat3b RenderOrtho(const Scene& s, const Grid& g, cv::Mat1i* ids) {
  const Raster r = RenderHeights(s, g, true, false, 0);
  *ids = r.id;
  cv::RNG rng(s.tex_seed);
  const double px_m = s.res / g.f;
  const cv::Size sz(g.w, g.h);
  const cv::Mat1f n_big = ValueNoise(sz, 25 / px_m, rng), n_mid = ValueNoise(sz, 4 / px_m, rng),
                  n_leaf = ValueNoise(sz, std::max(1.5, 0.9 / px_m), rng);
  cv::Mat1f fine(sz);
  rng.fill(fine, cv::RNG::NORMAL, 0.f, 1.f);
  const cv::Vec3b grass_a(55, 118, 72), grass_b(80, 145, 135), paving(150, 160, 168), plaza(168, 178, 185);
  cv::Mat3b img(sz);
  const Streets& L = s.lay;
  auto line_cov = [&](double d, double hw) { return std::clamp((hw + px_m / 2 - std::abs(d)) / px_m, 0.0, 1.0); };
  for (int y = 0; y < g.h; ++y) {
    for (int x = 0; x < g.w; ++x) {
      const uchar cl = r.cls(y, x);
      const double nf = fine(y, x), nb = n_big(y, x), nm = n_mid(y, x);
      cv::Vec3d col;
      if (cl == kRoof || cl == kRoofBox) {
        const Building& b = s.b[size_t(r.id(y, x))];
        col = cv::Vec3d(b.colour);
        double k = 1;
        if (cl == kRoofBox) {
          col = cv::Vec3d(190, 192, 195);
          k = 1 + 0.02 * nf;
        } else if (b.material < 10 && r.edge(y, x) < 0.45) {
          k = 1.12 + 0.03 * nf;  // parapet
        } else if (b.material < 10 && r.edge(y, x) < 0.9) {
          k = 0.9 + 0.03 * nf;
        } else if (b.material == 0) {
          k = 1 + 0.09 * nf + 0.1 * (nm - 0.5);
        } else if (b.material == 1) {
          k = 1 + 0.02 * nf + 0.1 * (nb - 0.5) - 0.06 * std::clamp((nm - 0.7) * 4, 0.0, 1.0);
        } else if (b.material == 2) {
          k = 1 + 0.05 * nf + 0.15 * (nm - 0.5);
        } else if (b.material == 3) {
          k = 1 + 0.1 * nf + 0.3 * (nm - 0.5);
        } else {
          // Tile rows / metal seams follow the roof's height contours.
          const double run = b.pitch > 0 ? r.roof(y, x) / b.pitch : 0;
          const double period = b.material == 10 ? 0.35 : 0.6;
          const double ph = std::fmod(run, period) / period;
          k = (b.material == 10 ? (ph < 0.25 ? 0.82 : 1.0) : (ph < 0.15 ? 1.12 : 1.0)) + 0.04 * nf +
              0.06 * (nm - 0.5);
        }
        col *= k;
      } else if (cl == kTree) {
        const Tree& t = s.t[size_t(r.tree_i(y, x))];
        const double q = r.tree_r(y, x), leaf = n_leaf(y, x);
        col = cv::Vec3d(t.colour) * (0.7 + 0.55 * leaf + 0.05 * nf) * (1.05 - 0.25 * q);
      } else if (cl == kWater) {  // swimming pool
        col = cv::Vec3d(200, 160, 60) * (1 + 0.04 * nf + 0.12 * (nm - 0.5));
      } else if (cl == kCoping) {
        col = cv::Vec3d(200, 205, 210) * (1 + 0.03 * nf);
      } else if (cl == kHedge) {
        col = cv::Vec3d(40, 92, 50) * (0.75 + 0.5 * n_leaf(y, x) + 0.05 * nf);
      } else {
        const RoadQuery q = L.Query(g.ToWorld(x, y).x, g.ToWorld(x, y).y);
        const double a0 = std::abs(q.m[0]) - q.hw[0], a1 = std::abs(q.m[1]) - q.hw[1];
        if (a0 < 0 || a1 < 0) {  // asphalt
          const double base = 78 + 14 * (Hash01(L.key, 99, q.main[0] * 2 + q.main[1]) - 0.5);
          const double v = base * (1 + 0.06 * nf + 0.12 * (nb - 0.5));
          col = cv::Vec3d(v * 1.02, v, v * 0.98);
          double paint = 0;
          cv::Vec3d paint_col(235, 235, 235);
          const bool cross = a0 < 0 && a1 < 0;
          if (!cross) {
            const int fam = a0 < 0 ? 0 : 1;
            const double m = q.m[fam], hw = q.hw[fam], other = fam == 0 ? a1 : a0;
            if (other < 4.5 && other > 0.8) {  // zebra crossing before the junction
              paint = (std::fmod(std::abs(m) + 100.0, 1.2) < 0.6 && std::abs(m) < hw - 0.5) ? 1 : 0;
            } else if (q.main[fam]) {
              paint = std::max(line_cov(m - 0.18, 0.075), line_cov(m + 0.18, 0.075));
              paint_col = cv::Vec3d(40, 190, 220);
              const double edge = std::max(line_cov(std::abs(m) - (hw - 0.5), 0.08), 0.0);
              if (edge > paint) paint = edge, paint_col = cv::Vec3d(235, 235, 235);
              const double lane = (std::fmod(q.along[fam] + 1e4, 12.0) < 4) ? line_cov(std::abs(m) - hw / 2, 0.07) : 0;
              if (lane > paint) paint = lane, paint_col = cv::Vec3d(235, 235, 235);
            } else if (std::fmod(q.along[fam] + 1e4, 9.0) < 3) {
              paint = line_cov(m, 0.07);
            }
          }
          col = col * (1 - 0.85 * paint) + paint_col * (0.85 * paint);
        } else if (a0 < L.sidewalk || a1 < L.sidewalk) {  // sidewalk slabs
          const int fam = a0 < L.sidewalk ? 0 : 1;
          const double seam = line_cov(std::fmod(q.along[fam] + 1e4, 1.5) - 0.75, 0.04);
          const double v = 172 * (1 + 0.03 * nf + 0.06 * (nb - 0.5)) * (1 - 0.15 * seam);
          col = cv::Vec3d(v * 1.02, v, v * 0.97);
          if (std::min(a0, a1) < 0.25) col *= 0.85;  // kerb
        } else {
          const double bt = Hash01(L.key, q.block[0] * 131 + 7, q.block[1]);
          double pav = bt < 0.3 ? 0 : bt < 0.42 ? 1 : std::clamp((nb - 0.62) * 6, 0.0, 1.0);
          const cv::Vec3d grass = cv::Vec3d(grass_a) * (1 - nm * 0.6) + cv::Vec3d(grass_b) * (nm * 0.6);
          const cv::Vec3d pv = bt < 0.42 ? cv::Vec3d(plaza) : cv::Vec3d(paving);
          col = grass * (1 - pav) * (1 + 0.08 * nf) + pv * pav * (1 + 0.04 * nf + 0.08 * (nm - 0.5));
        }
        if (cl == kCar) col = cv::Vec3d(0, 0, 0);  // painted below
      }
      img(y, x) = cv::Vec3b(Sat(col[0]), Sat(col[1]), Sat(col[2]));
    }
  }
  // Parking lots: asphalt with stall lines (ground pixels only).
  for (const Lot& lot : s.lots) {
    const cv::Rect bb = PixBox(lot.poly, g, 1);
    const cv::Rect bc = bb & cv::Rect(0, 0, g.w, g.h);
    if (bc.empty()) continue;
    const cv::Mat1b bm = PolyMask(lot.poly, {}, g, bb);
    for (int y = bc.y; y < bc.y + bc.height; ++y)
      for (int x = bc.x; x < bc.x + bc.width; ++x) {
        if (!bm(y - bb.y, x - bb.x) || (r.cls(y, x) != kGround && r.cls(y, x) != kCar)) continue;
        const cv::Point2d w = (g.ToWorld(x, y) - lot.origin) * s.res;
        const double u = w.dot(lot.u), v = w.dot(lot.v), vv = std::fmod(v, 17.5);
        const bool stall = vv < 5 || (vv >= 11.5 && vv < 16.5);
        double paint = stall ? line_cov(std::fmod(u - 0.5 + 25.0, 2.5) - 1.25, 0.06) : 0;
        if (vv >= 16.5) paint = 0.6;  // kerbed island
        const double a = 82 * (1 + 0.05 * fine(y, x) + 0.1 * (n_big(y, x) - 0.5));
        const cv::Vec3d col = cv::Vec3d(a * 1.02, a, a * 0.98) * (1 - 0.85 * paint) + cv::Vec3d(225, 225, 225) * (0.85 * paint);
        img(y, x) = cv::Vec3b(Sat(col[0]), Sat(col[1]), Sat(col[2]));
      }
  }
  // Cars: body, windscreen and rear window.
  for (const Car& c : s.cars) {
    const cv::Rect bb = PixBox(c.poly, g, 1);
    if ((bb & cv::Rect(0, 0, g.w, g.h)).empty()) continue;
    auto poly = ToFixed(c.poly, g, {0, 0});
    cv::fillConvexPoly(img, poly, cv::Scalar(c.colour[0], c.colour[1], c.colour[2]), cv::LINE_AA, 8);
    const cv::Point2d f0 = c.poly[0], f1 = c.poly[1], b1 = c.poly[2], b0 = c.poly[3];
    auto lerp = [](cv::Point2d a, cv::Point2d b, double t) { return a + (b - a) * t; };
    for (auto [t0, t1] : {std::pair{0.22, 0.4}, std::pair{0.75, 0.86}}) {
      std::vector<cv::Point2d> wnd{lerp(lerp(f0, b0, t0), lerp(f1, b1, t0), 0.1), lerp(lerp(f0, b0, t0), lerp(f1, b1, t0), 0.9),
                                   lerp(lerp(f0, b0, t1), lerp(f1, b1, t1), 0.9), lerp(lerp(f0, b0, t1), lerp(f1, b1, t1), 0.1)};
      cv::fillConvexPoly(img, ToFixed(wnd, g, {0, 0}), cv::Scalar(45, 40, 38), cv::LINE_AA, 8);
    }
  }
  // Sun: Lambert shading of sloped roofs and crowns, then cast shadows.
  const double az = s.sun_az * kPi / 180, el = s.sun_el * kPi / 180;
  const cv::Vec3d sun(std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el));
  const double amb = 0.4, flat = amb + (1 - amb) * sun[2];
  // Occluders on a coarse grid (depth resolution) that reaches beyond g by the longest shadow.
  const double reach = 45 / std::tan(el) / s.res + 4;
  Grid cg = GridOver(cv::Rect2d(g.x0 - reach, g.y0 - reach, g.w / g.f + 2 * reach, g.h / g.f + 2 * reach), 1);
  const Raster cr = RenderHeights(s, cg, false, false, 0);
  const cv::Mat1f M = OccluderField(cr.h, s.res, s.sun_az, s.sun_el);
  // Sample M at ortho pixel centres: coarse u = ortho world x - cg.x0 - 0.5.
  cv::Matx23d A(1 / g.f, 0, 0.5 / g.f + g.x0 - cg.x0 - 0.5, 0, 1 / g.f, 0.5 / g.f + g.y0 - cg.y0 - 0.5);
  cv::Mat1f Mo;
  cv::warpAffine(M, Mo, A, sz, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  cv::Mat1f shadow(sz);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) shadow(y, x) = float(std::clamp((Mo(y, x) - r.h(y, x) - 0.15) / 0.5, 0.0, 1.0));
  cv::GaussianBlur(shadow, shadow, cv::Size(), std::max(0.5, 0.25 / px_m));
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) {
      const double gx = r.gx(y, x), gy = r.gy(y, x);
      double k = 1;
      if (gx != 0 || gy != 0) {
        const double n = std::sqrt(gx * gx + gy * gy + 1);
        const double ns = (-gx * sun[0] - gy * sun[1] + sun[2]) / n;
        k = std::clamp((amb + (1 - amb) * std::max(0.0, ns)) / flat, 0.35, 1.6);
      }
      const double sh = shadow(y, x);
      cv::Vec3b& p = img(y, x);
      const double kb = k * (1 - sh * 0.38), kg = k * (1 - sh * 0.48), kr = k * (1 - sh * 0.54);
      p = cv::Vec3b(Sat(p[0] * kb), Sat(p[1] * kg), Sat(p[2] * kr));
    }
  if (s.style != Style::kClassic) ApplyLean(s, g, r, img, ids);
  return img;
}

// ----------------------------------------------------------------------------
struct PhotoGeometry {
  cv::Matx33d H;  // photo -> world (depth pixels)
  cv::Size size;
  double scale, rot_deg;
  cv::Point2d persp;
};

std::vector<cv::Point2d> PhotoCorners(const PhotoGeometry& p) {
  std::vector<cv::Point2d> in{{-0.5, -0.5}, {p.size.width - 0.5, -0.5}, {p.size.width - 0.5, p.size.height - 0.5},
                              {-0.5, p.size.height - 0.5}}, out;
  cv::perspectiveTransform(in, out, cv::Mat(p.H));
  return out;
}

PhotoGeometry MakePhotoGeometry(Rng& r, const CityOptions& o) {
  PhotoGeometry p;
  p.scale = std::exp(r.U(std::log(o.min_scale), std::log(o.max_scale)));
  const double th = r.U(0, 2 * kPi);
  p.rot_deg = th * 180 / kPi;
  const double L = r.U(o.min_coverage, o.max_coverage) * std::max(o.width, o.height);
  const double aspect = std::exp(r.U(std::log(0.75), std::log(1.33)));
  double pw = L * std::sqrt(aspect) / p.scale, ph = L / std::sqrt(aspect) / p.scale;
  const double k = std::min(1.0, o.photo_max_side / std::max(pw, ph));
  pw = std::max(32.0, pw * k), ph = std::max(32.0, ph * k);
  p.size = cv::Size(int(std::lround(pw)), int(std::lround(ph)));
  const double phi = r.U(0, 2 * kPi), mag = o.max_perspective * r.U();
  const double den = std::abs(std::cos(phi)) * p.size.width / 2 + std::abs(std::sin(phi)) * p.size.height / 2;
  p.persp = cv::Point2d(mag * std::cos(phi) / den, mag * std::sin(phi) / den);
  const cv::Point2d pc((p.size.width - 1) / 2.0, (p.size.height - 1) / 2.0);
  const cv::Matx33d Tm(1, 0, -pc.x, 0, 1, -pc.y, 0, 0, 1);
  const cv::Matx33d P(1, 0, 0, 0, 1, 0, p.persp.x, p.persp.y, 1);
  const double c = std::cos(th) * p.scale, s = std::sin(th) * p.scale;
  const cv::Matx33d RS(c, -s, 0, s, c, 0, 0, 0, 1);
  cv::Point2d centre;
  if (o.overlap) {
    centre = cv::Point2d(r.U(0.1, 0.9) * (o.width - 1), r.U(0.1, 0.9) * (o.height - 1));
  } else {
    p.H = RS * P * Tm;
    double rad = 0;
    for (const auto& q : PhotoCorners(p)) rad = std::max(rad, cv::norm(q));
    const double psi = r.U(0, 2 * kPi), D = std::hypot(o.width, o.height) / 2 + rad + 10;
    centre = cv::Point2d((o.width - 1) / 2.0 + D * std::cos(psi), (o.height - 1) / 2.0 + D * std::sin(psi));
  }
  const cv::Matx33d Tc(1, 0, centre.x, 0, 1, centre.y, 0, 0, 1);
  p.H = Tc * RS * P * Tm;
  return p;
}

cv::Rect2d BoundsOf(const std::vector<cv::Point2d>& pts) {
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const auto& p : pts) x0 = std::min(x0, p.x), y0 = std::min(y0, p.y), x1 = std::max(x1, p.x), y1 = std::max(y1, p.y);
  return {x0, y0, x1 - x0, y1 - y0};
}

void SensorEffects(cv::Mat3b& img, Rng& r, const CityOptions& o) {
  cv::Mat3f f;
  img.convertTo(f, CV_32F);
  const cv::Vec3f gain(float(r.U(0.92, 1.08)), float(r.U(0.95, 1.05)), float(r.U(0.92, 1.08)));
  const float bright = float(r.U(0.85, 1.15)), haze = float(r.U(0, 25));
  const double cx = f.cols / 2.0, cy = f.rows / 2.0, rr = cx * cx + cy * cy, vig = r.U(0, 0.2);
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x < f.cols; ++x) {
      const float v = float(1 - vig * ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / rr);
      cv::Vec3f& p = f(y, x);
      for (int k = 0; k < 3; ++k) p[k] = (p[k] * gain[k] * bright * v) * (1 - haze / 255) + haze;
    }
  const double sigma = r.U(0, o.photo_blur);
  if (sigma > 0.2) cv::GaussianBlur(f, f, cv::Size(), sigma);
  const double noise = r.U(0, o.photo_noise);
  if (noise > 0) {
    cv::RNG rng(r.Next());
    cv::Mat3f n(f.size());
    rng.fill(n, cv::RNG::NORMAL, 0.f, float(noise));
    f += n;
  }
  f.convertTo(img, CV_8U);
}

}  // namespace

// ----------------------------------------------------------------------------
const char* RoofTypeName(RoofType r) {
  switch (r) {
    case RoofType::kGable: return "gable";
    case RoofType::kHip: return "hip";
    case RoofType::kShed: return "shed";
    case RoofType::kDome: return "dome";
    default: return "flat";
  }
}

const std::vector<std::string>& CityStyles() {
  static const std::vector<std::string> all{"classic", "suburb", "dense", "civic"};
  return all;
}

void CityOptions::Check() const {
  auto req = [](bool ok, const std::string& m) { Require(ok, ErrorCode::kInvalidArgument, m); };
  req(width >= 64 && width <= 20000 && height >= 64 && height <= 20000, "city: width and height must be in 64..20000");
  req(buildings >= 0 && buildings <= 5000, "city: buildings must be in 0..5000");
  req(res_m >= 0.05 && res_m <= 5, "city: res_m must be in 0.05..5");
  req(trees >= 0 && trees <= 100000, "city: trees must be in 0..100000");
  req(min_scale > 0.01 && min_scale <= max_scale && max_scale <= 100, "city: need 0.01 < min_scale <= max_scale <= 100");
  req(max_perspective >= 0 && max_perspective <= 0.5, "city: max_perspective must be in 0..0.5");
  req(sun_azimuth_deg < 360, "city: sun_azimuth_deg must be < 360 (negative: random)");
  req(sun_elevation_deg < 0 || (sun_elevation_deg >= 10 && sun_elevation_deg <= 90),
      "city: sun_elevation_deg must be in 10..90 (negative: random)");
  req(missing_returns >= 0 && missing_returns <= 0.5, "city: missing_returns must be in 0..0.5");
  req(depth_noise_m >= 0 && depth_noise_m <= 10, "city: depth_noise_m must be in 0..10");
  req(ground_slope >= 0 && ground_slope <= 0.2, "city: ground_slope must be in 0..0.2");
  req(photo_max_side >= 64 && photo_max_side <= 20000, "city: photo_max_side must be in 64..20000");
  req(min_coverage > 0.05 && min_coverage <= max_coverage && max_coverage <= 3,
      "city: need 0.05 < min_coverage <= max_coverage <= 3");
  req(photo_blur >= 0 && photo_blur <= 10 && photo_noise >= 0 && photo_noise <= 100, "city: photo_blur/photo_noise out of range");
  req(std::find(CityStyles().begin(), CityStyles().end(), style) != CityStyles().end(),
      "city: style must be classic, suburb, dense or civic");
}

double PhotoOverlap(const cv::Matx33d& H, cv::Size photo, cv::Size depth) {
  const int n = 64;
  int in = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const cv::Vec3d p = H * cv::Vec3d((j + 0.5) * photo.width / n - 0.5, (i + 0.5) * photo.height / n - 0.5, 1);
      if (p[2] <= 0) continue;
      const double x = p[0] / p[2], y = p[1] / p[2];
      in += x >= -0.5 && y >= -0.5 && x < depth.width - 0.5 && y < depth.height - 0.5;
    }
  return double(in) / (n * n);
}


namespace {

// ----------------------------------------------------------------------------
// Styles other than classic: what goes around a building, once it is placed.

// Marks `poly` taken if it lies on free ground inside the placement grid.
bool TryPlaceFree(Placer& P, const std::vector<cv::Point2d>& poly) {
  const cv::Rect box = PixBox(poly, P.g, 1);
  if ((box & cv::Rect(0, 0, P.g.w, P.g.h)) != box) return false;
  const cv::Mat1b m = PolyMask(poly, {}, P.g, box);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      if (m(y, x) && P.occ(box.y + y, box.x + x)) return false;
  std::vector<std::vector<cv::Point>> o{ToFixed(poly, P.g, {0, 0})};
  cv::fillPoly(P.occ, o, cv::Scalar(2), cv::LINE_8, 8);
  return true;
}

// An oriented rectangle (world px) from a centre (world px), unit axes and half sizes in metres.
std::vector<cv::Point2d> OrientedRect(cv::Point2d c, cv::Point2d a, cv::Point2d b, double ha_m, double hb_m, double res) {
  const cv::Point2d A = a * (ha_m / res), B = b * (hb_m / res);
  return {c - A - B, c + A - B, c + A + B, c - A + B};
}

struct Frame {  // a building's frame: `away` from its street, `side` along it, extents in metres
  cv::Point2d away, side;
  double lo_a, hi_a, lo_s, hi_s;
};

Frame FrameOf(const Streets& L, const Building& b, double res) {
  const RoadQuery q = L.Query(b.centre.x, b.centre.y);
  const int fam = std::abs(q.m[0]) - q.hw[0] < std::abs(q.m[1]) - q.hw[1] ? 0 : 1;
  Frame f;
  f.away = L.AcrossAt(fam, b.centre) * (q.m[fam] >= 0 ? 1.0 : -1.0);
  f.side = cv::Point2d(-f.away.y, f.away.x);
  f.lo_a = f.lo_s = 1e18, f.hi_a = f.hi_s = -1e18;
  for (const auto& p : b.outer) {
    const double a = (p - b.centre).dot(f.away) * res, sd = (p - b.centre).dot(f.side) * res;
    f.lo_a = std::min(f.lo_a, a), f.hi_a = std::max(f.hi_a, a), f.lo_s = std::min(f.lo_s, sd), f.hi_s = std::max(f.hi_s, sd);
  }
  return f;
}

void AddGarden(Rng& r, Scene& s, Placer& P, const Building& b, Style style, std::vector<Building>* minors) {
  const double res = s.res;
  const Frame f = FrameOf(s.lay, b, res);
  auto at = [&](double a_m, double s_m) { return b.centre + (f.away * a_m + f.side * s_m) / res; };
  // Swimming pool behind the house, with its coping.
  if (r.B(style == Style::kSuburb ? 0.5 : 0.3)) {
    const double pw = r.U(3, 5), pd = r.U(5, 10), off = r.U(3, 6);
    const bool along = r.B(0.5);
    const double ha = (along ? pd : pw) / 2, hs = (along ? pw : pd) / 2;
    const cv::Point2d c = at(f.hi_a + off + ha, r.U(f.lo_s + hs, std::max(f.lo_s + hs, f.hi_s - hs)));
    const auto coping = OrientedRect(c, f.away, f.side, ha + 0.6, hs + 0.6, res);
    if (TryPlaceFree(P, coping)) {
      s.patches.push_back({Patch::kCoping, coping, 0});
      s.patches.push_back({Patch::kWater, OrientedRect(c, f.away, f.side, ha, hs, res), 0});
    }
  }
  // Garden shed in a back corner (a small building, not counted).
  if (r.B(0.5)) {
    const double sw = r.U(2, 3.2), sd = r.U(2.2, 4);
    const double side = r.B(0.5) ? f.hi_s + r.U(-1, 3) : f.lo_s - r.U(-1, 3);
    const cv::Point2d c = at(f.hi_a + r.U(5, 12), side);
    Building sh;
    sh.outer = OrientedRect(c, f.away, f.side, sd / 2, sw / 2, res);
    sh.centre = c;
    sh.shape = "rect";
    sh.eave_m = r.U(2.0, 2.6);
    if (r.B(0.5)) sh.roof = RoofType::kShed, sh.pitch = std::tan(10 * kPi / 180), sh.short_axis = f.side, sh.half_short_m = sw / 2;
    PickRoofMaterial(r, sh);
    if (TryPlaceFree(P, sh.outer)) minors->push_back(sh);
  }
  // Hedges on the plot boundary (front one less often), never across roads or buildings.
  const double back = f.hi_a + r.U(10, 18), front = f.lo_a - r.U(1.5, 3.5);
  const double left = f.lo_s - r.U(3, 6), right = f.hi_s + r.U(3, 6);
  const double hw = r.U(0.35, 0.65), hh = r.U(1.2, 2.6);
  struct Seg { double a0, s0, a1, s1, p; };
  for (const Seg& g : {Seg{back, left, back, right, 0.6}, Seg{front, left, back, left, 0.6}, Seg{front, right, back, right, 0.6},
                       Seg{front, left, front, right, 0.3}}) {
    if (!r.B(g.p)) continue;
    const cv::Point2d a = at(g.a0, g.s0), e = at(g.a1, g.s1);
    const cv::Point2d d = e - a;
    const double len = cv::norm(d);
    if (len < 1) continue;
    bool ok = true;
    for (int k = 0; k <= 8 && ok; ++k) {
      const cv::Point2d q = a + d * (k / 8.0);
      const cv::Point2d pix = P.g.ToPix(q);
      const int x = int(std::lround(pix.x)), y = int(std::lround(pix.y));
      ok = x >= 0 && y >= 0 && x < P.g.w && y < P.g.h && P.occ(y, x) != 2 && !OnRoad(s.lay.Query(q.x, q.y), s.lay.sidewalk);
    }
    if (!ok) continue;
    const cv::Point2d u = d / len, n(-u.y, u.x);
    const cv::Point2d nn = n * (hw / res);
    s.patches.push_back({Patch::kHedge, {a - nn, e - nn, e + nn, a + nn}, hh});
  }
}

// A parking lot beside a hall, with rows of stalls and parked cars.
void AddLot(Rng& r, Scene& s, Placer& P, const Building& b, std::vector<Car>* parked) {
  const double res = s.res;
  const Frame f = FrameOf(s.lay, b, res);
  const double d0 = r.U(18, 36), la = f.hi_a - f.lo_a;
  const int first = r.B(0.5) ? 1 : -1;
  for (int attempt = 0; attempt < 4; ++attempt) {  // one side, the other, then both at 60 % depth
    const double sg = attempt % 2 ? -first : first, d = attempt < 2 ? d0 : std::max(12.0, 0.6 * d0);
    const double s0 = sg > 0 ? f.hi_s + 3 : f.lo_s - 3 - d;
    const cv::Point2d origin = b.centre + (f.away * f.lo_a + f.side * s0) / res;
    Lot lot;
    lot.origin = origin, lot.u = f.away, lot.v = f.side, lot.w_m = la, lot.d_m = d;
    lot.poly = {origin, origin + f.away * (la / res), origin + (f.away * la + f.side * d) / res, origin + f.side * (d / res)};
    if (!TryPlaceFree(P, lot.poly)) continue;
    s.lots.push_back(lot);
    const double fill = r.U(0.5, 0.95);
    for (double v0 = 0; v0 + 5 <= d; v0 += 17.5)
      for (double v : {v0, v0 + 11.5}) {
        if (v + 5 > d) continue;
        for (double u = 0.5; u + 2.5 <= la - 0.5; u += 2.5) {
          if (!r.B(fill)) continue;
          const double len = r.U(4.0, 4.9), wid = r.U(1.7, 1.95);
          const cv::Point2d c = origin + (f.away * (u + 1.25) + f.side * (v + 2.5)) / res;
          const cv::Point2d fwd = f.side * (r.B(0.5) ? 1.0 : -1.0), acr(-fwd.y, fwd.x);
          Car car;
          const cv::Point2d F = fwd * (len / 2 / res), A = acr * (wid / 2 / res);
          car.poly = {c + F - A, c + F + A, c - F + A, c - F - A};
          car.colour = r.Pick(std::vector<cv::Vec3b>{{30, 30, 30}, {230, 230, 230}, {160, 160, 165}, {40, 40, 170},
                                                       {150, 80, 30}, {60, 60, 60}, {200, 200, 205}, {40, 120, 200}});
          parked->push_back(car);
        }
      }
    break;
  }
}

// Conventional (not true) orthophoto: a point h metres up shows h * lean further on.
// Per output pixel, the ray is marched down from the highest point that can reach it;
// the first surface it meets is what the photo shows (a roof, or a facade band).
void ApplyLean(const Scene& s, const Grid& g, const Raster& r, cv::Mat3b& img, cv::Mat1i* ids) {
  const cv::Point2d L = s.lean_px * g.f;  // ortho px per metre of height
  const double Ln = cv::norm(L);
  double hmax = 0;
  cv::minMaxLoc(r.h, nullptr, &hmax);
  if (Ln < 1e-9 || hmax <= 0.3) return;
  const double dt = 0.5 / Ln;  // half a pixel per step
  const int T = 16, tw = (g.w + T - 1) / T, th = (g.h + T - 1) / T;
  cv::Mat1f tile(th, tw, 0.f);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) tile(y / T, x / T) = std::max(tile(y / T, x / T), r.h(y, x));
  // Highest point whose lean can reach each tile.
  cv::Mat1f reach(th, tw, 0.f);
  const int steps = int(std::ceil(hmax * Ln / T)) + 1;
  for (int ty = 0; ty < th; ++ty)
    for (int tx = 0; tx < tw; ++tx) {
      float m = 0;
      for (int k = 0; k <= steps; ++k) {
        const double t = hmax * k / steps;
        const int cx = int(std::floor((tx * T + T / 2.0 - t * L.x) / T)), cy = int(std::floor((ty * T + T / 2.0 - t * L.y) / T));
        for (int yy = cy - 1; yy <= cy + 1; ++yy)
          for (int xx = cx - 1; xx <= cx + 1; ++xx)
            if (xx >= 0 && yy >= 0 && xx < tw && yy < th) m = std::max(m, tile(yy, xx));
      }
      reach(ty, tx) = m;
    }
  const cv::Mat3b src = img.clone();
  const cv::Mat1i sid = ids->clone();
  const double wall_tol = std::max(0.6, 1.2 * dt);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) {
      const double top = reach(y / T, x / T);
      if (top <= 0.3) continue;
      bool hit = false;
      double t = top;
      int px = x, py = y;
      for (; t > 0.05; t -= dt) {
        px = int(std::lround(x - t * L.x)), py = int(std::lround(y - t * L.y));
        if (px < 0 || py < 0 || px >= g.w || py >= g.h) continue;
        if (r.h(py, px) >= t) { hit = true; break; }
      }
      if (!hit) {  // the ground at this pixel
        if (r.h(y, x) > 0.3) (*ids)(y, x) = -1, img(y, x) = src(y, x);
        continue;
      }
      const uchar c = r.cls(py, px);
      const bool wall = r.h(py, px) - t > wall_tol;
      if (wall && (c == kRoof || c == kRoofBox) && r.id(py, px) >= 0) {
        const cv::Vec3d w = cv::Vec3d(s.b[size_t(r.id(py, px))].wall) * (std::fmod(t, 3.0) < 1.1 ? 0.62 : 0.85);
        img(y, x) = cv::Vec3b(Sat(w[0]), Sat(w[1]), Sat(w[2]));
        (*ids)(y, x) = -1;
      } else if (wall) {
        const cv::Vec3b v = src(py, px);
        img(y, x) = cv::Vec3b(Sat(v[0] * 0.75), Sat(v[1] * 0.75), Sat(v[2] * 0.75));
        (*ids)(y, x) = -1;
      } else {
        img(y, x) = src(py, px);
        (*ids)(y, x) = (c == kRoof || c == kRoofBox) ? sid(py, px) : -1;
      }
    }
}

Style ParseStyle(const std::string& name) {
  const auto& all = CityStyles();
  for (size_t i = 0; i < all.size(); ++i)
    if (all[i] == name) return Style(i);
  throw Error(ErrorCode::kInvalidArgument, "city: unknown style '" + name + "'");
}

}  // namespace

City MakeCity(const CityOptions& o, std::uint64_t seed) {
  o.Check();
  const Style style = ParseStyle(o.style);
  const bool styled = style != Style::kClassic;
  // Each style its own draws for a seed (classic: as it always was).
  Rng r(SplitMix(seed) ^ 0x6369747973796e74ull ^ (styled ? SplitMix(std::uint64_t(style)) : 0));
  City city;
  city.options = o;
  city.seed = seed;
  Scene s;
  s.res = o.res_m;
  s.tex_seed = r.Next();
  // drawn whether or not they are given: a scene with another sun is the
  // same scene (the shadows' effect can be measured alone)
  const double sun_az = r.U(0, 360), sun_el = r.U(30, 65);
  s.sun_az = o.sun_azimuth_deg >= 0 ? o.sun_azimuth_deg : sun_az;
  s.sun_el = o.sun_elevation_deg >= 0 ? o.sun_elevation_deg : sun_el;
  s.lay.alpha = r.U(0, kPi / 2);
  s.lay.ca = std::cos(s.lay.alpha), s.lay.sa = std::sin(s.lay.alpha);
  s.lay.res = o.res_m;
  s.lay.spacing[0] = r.U(90, 150), s.lay.spacing[1] = r.U(90, 150);
  s.lay.key = r.Next();
  s.style = style;
  if (styled) {  // a second, rotated street grid beyond a line (most towns of the styles have one)
    if (r.B(style == Style::kDense ? 0.4 : 0.6)) {
      Layout a = s.lay;
      a.alpha = std::fmod(s.lay.alpha + r.U(0.25, 0.65) * (r.B(0.5) ? 1 : -1) + kPi, kPi / 2);
      a.ca = std::cos(a.alpha), a.sa = std::sin(a.alpha);
      a.spacing[0] = r.U(70, 130), a.spacing[1] = r.U(70, 130);
      a.key = r.Next();
      s.lay.alt.push_back(a);
      const double phi = r.U(0, 2 * kPi);
      s.lay.split_n = cv::Point2d(std::cos(phi), std::sin(phi));
      const cv::Point2d c(r.U(0.25, 0.75) * o.width, r.U(0.25, 0.75) * o.height);
      s.lay.split_d = c.dot(s.lay.split_n);
    }
    if (style == Style::kSuburb) s.lay.spacing[0] = r.U(70, 120), s.lay.spacing[1] = r.U(60, 110);
    const double la = r.U(0, 2 * kPi), lm = r.U(0.05, 0.2);  // lean, metres per metre of height
    s.lean_px = cv::Point2d(std::cos(la), std::sin(la)) * (lm / o.res_m);
    city.lean = cv::Point2d(std::cos(la), std::sin(la)) * lm;
  }

  PhotoGeometry pg = MakePhotoGeometry(r, o);
  const std::vector<cv::Point2d> foot = PhotoCorners(pg);
  const cv::Rect2d fb = BoundsOf(foot);
  const cv::Rect2d depth_rect(-0.5, -0.5, o.width, o.height);
  const cv::Rect2d world = (fb | depth_rect);

  // Occupancy over the world: roads and sidewalks are taken.
  Placer P;
  P.g = GridOver(cv::Rect2d(world.x - 8, world.y - 8, world.width + 16, world.height + 16), 1);
  P.occ = cv::Mat1b(P.g.h, P.g.w, uchar(0));
  P.zone = cv::Mat1b(P.g.h, P.g.w, uchar(2));
  const double gap = 2.0 / o.res_m;
  for (int y = 0; y < P.g.h; ++y)
    for (int x = 0; x < P.g.w; ++x) {
      const cv::Point2d w = P.g.ToWorld(x, y);
      if (OnRoad(s.lay.Query(w.x, w.y), s.lay.sidewalk + 0.5)) P.occ(y, x) = 1;
      const bool in = w.x >= 3 && w.y >= 3 && w.x <= o.width - 4 && w.y <= o.height - 4;
      const bool near = w.x >= -4 && w.y >= -4 && w.x <= o.width + 3 && w.y <= o.height + 3;
      P.zone(y, x) = in ? 1 : near ? 0 : 2;
    }
  // Photo area outside the depth raster, for the density of the extra content.
  double outside_frac = 0;
  {
    cv::Mat1b fm(P.g.h, P.g.w, uchar(0));
    std::vector<std::vector<cv::Point>> fp{ToFixed(foot, P.g, {0, 0})};
    cv::fillPoly(fm, fp, cv::Scalar(255), cv::LINE_8, 8);
    int n = 0;
    for (int y = 0; y < P.g.h; ++y)
      for (int x = 0; x < P.g.w; ++x) n += fm(y, x) && P.zone(y, x) == 2;
    outside_frac = double(n) / (double(o.width) * o.height);
  }
  auto sample_in = [&](int zone) {
    if (zone == 1) return cv::Point2d(r.U(0, o.width - 1), r.U(0, o.height - 1));
    return cv::Point2d(r.U(fb.x, fb.x + fb.width), r.U(fb.y, fb.y + fb.height));
  };
  const int n_out = int(std::lround(o.buildings * outside_frac));
  std::vector<Building> minors;  // sheds (styles)
  std::vector<Car> parked;       // cars in parking lots (styles)
  for (int zone : {1, 2}) {
    const int want = zone == 1 ? o.buildings : n_out;
    int placed = 0;
    for (int attempt = 0; placed < want && attempt < 400 * std::max(1, want); ++attempt) {
      std::string kind;
      Building b = styled ? MakeStyledBuilding(r, s, sample_in(zone), style, o.pitched_roofs, &kind)
                          : MakeBuilding(r, s, sample_in(zone), o.pitched_roofs);
      auto shrink = [&b](double k) {
        for (auto* ring : {&b.outer}) for (auto& p : *ring) p = b.centre + (p - b.centre) * k;
        for (auto& hole : b.holes) for (auto& p : hole) p = b.centre + (p - b.centre) * k;
        for (auto& bx : b.boxes) for (auto& p : bx.poly) p = b.centre + (p - b.centre) * k;
        b.half_short_m *= k;
      };
      if (styled) {  // small tiles: no building longer than 40 % of the tile's short side
        const cv::Rect2d bb = BoundsOf(b.outer);
        const double cap = 0.4 * std::min(o.width, o.height);
        if (std::max(bb.width, bb.height) > cap) shrink(cap / std::max(bb.width, bb.height));
      }
      if (attempt > 100 * want) shrink(0.6);  // crowded: shrink
      if (styled && attempt > 200 * want) shrink(0.6);
      if (r.B(kind == "house" ? 0.9 : 0.6)) FaceStreet(r, s.lay, b);
      if (!TryPlace(P, b.outer, zone, gap)) continue;
      if (kind == "house") AddGarden(r, s, P, b, style, &minors);
      if (kind == "hall") AddLot(r, s, P, b, &parked);
      s.b.push_back(std::move(b));
      ++placed;
    }
    if (zone == 1) s.counted = placed;
    else city.outside_buildings = placed;
  }
  s.first_minor = int(s.b.size());
  city.minor_structures = int(minors.size());
  city.parking_lots = int(s.lots.size());
  for (Building& m : minors) s.b.push_back(std::move(m));
  // Trees: clusters, street trees on sidewalks, single trees; never on buildings or roads.
  const int n_trees_out = int(std::lround(o.trees * outside_frac));
  for (int zone : {1, 2}) {
    const int want = zone == 1 ? o.trees : n_trees_out;
    int placed = 0;
    cv::Point2d last(-1e9, -1e9);
    for (int attempt = 0; placed < want && attempt < 50 * std::max(1, want); ++attempt) {
      Tree t;
      t.r_m = r.U(2.5, 6);
      t.h_m = std::clamp(t.r_m * 2.2 + 2 * r.N(), 4.0, 20.0);
      t.colour = Jitter(r, r.Pick(std::vector<cv::Vec3b>{{42, 100, 52}, {36, 86, 48}, {52, 112, 72}, {34, 72, 44}, {45, 105, 85}}), 0.1);
      for (double& l : t.lobes) l = r.U(0, 2 * kPi);
      const double mode = r.U();
      if (mode < 0.45 && last.x > -1e8) {
        const double a = r.U(0, 2 * kPi), d = r.U(1.6, 2.6) * t.r_m / o.res_m;
        t.c = last + cv::Point2d(std::cos(a), std::sin(a)) * d;
      } else {
        t.c = sample_in(zone);
        if (mode > 0.75) {  // street tree: move onto the nearest sidewalk
          const RoadQuery q = s.lay.Query(t.c.x, t.c.y);
          const int fam = std::abs(q.m[0]) - q.hw[0] < std::abs(q.m[1]) - q.hw[1] ? 0 : 1;
          const double target = (q.m[fam] >= 0 ? 1 : -1) * (q.hw[fam] + 1.5);
          t.c += s.lay.Across(fam) * ((target - q.m[fam]) / o.res_m);
        }
      }
      const int cx = int(std::lround(P.g.ToPix(t.c).x)), cy = int(std::lround(P.g.ToPix(t.c).y));
      if (cx < 0 || cy < 0 || cx >= P.g.w || cy >= P.g.h) continue;
      if (P.zone(cy, cx) != zone && !(zone == 1 && P.zone(cy, cx) == 0)) continue;
      if (OnRoad(s.lay.Query(t.c.x, t.c.y), 0.5)) continue;
      const int rp = int(std::ceil(t.r_m * 1.1 / o.res_m));
      bool free = true;
      for (int y = std::max(0, cy - rp); y <= std::min(P.g.h - 1, cy + rp) && free; ++y)
        for (int x = std::max(0, cx - rp); x <= std::min(P.g.w - 1, cx + rp); ++x)
          if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= rp * rp && P.occ(y, x) == 2) { free = false; break; }
      if (!free) continue;
      s.t.push_back(t);
      last = t.c;
      ++placed;
    }
  }
  // Cars on the roads: sample positions, keep those on a lane outside junctions.
  {
    const double area_m2 = world.width * world.height * o.res_m * o.res_m;
    const int samples = int(area_m2 / 250);
    for (int i = 0; i < samples; ++i) {
      const cv::Point2d c(r.U(world.x, world.x + world.width), r.U(world.y, world.y + world.height));
      const RoadQuery q = s.lay.Query(c.x, c.y);
      const bool in0 = std::abs(q.m[0]) < q.hw[0], in1 = std::abs(q.m[1]) < q.hw[1];
      if (in0 == in1 || !r.B(0.6)) continue;
      const int fam = in0 ? 0 : 1;
      if (std::abs(q.m[1 - fam]) < q.hw[1 - fam] + 8) continue;  // not near a junction
      const double side = q.m[fam] >= 0 ? 1 : -1;
      const double lane = side * (q.main[fam] ? (r.B(0.5) ? q.hw[fam] * 0.25 : q.hw[fam] * 0.72) : q.hw[fam] * 0.45);
      const cv::Point2d across = s.lay.Across(fam), along(-across.y, across.x);
      const cv::Point2d ctr = c + across * ((lane - q.m[fam]) / o.res_m);
      const double len = r.U(4.0, 5.0) / o.res_m / 2, wid = r.U(1.7, 1.95) / o.res_m / 2;
      const cv::Point2d fwd = along * (side > 0 ? 1.0 : -1.0);
      Car car;
      car.poly = {ctr + fwd * len - across * wid, ctr + fwd * len + across * wid, ctr - fwd * len + across * wid,
                  ctr - fwd * len - across * wid};
      car.colour = r.Pick(std::vector<cv::Vec3b>{{30, 30, 30}, {230, 230, 230}, {160, 160, 165}, {40, 40, 170},
                                                   {150, 80, 30}, {60, 60, 60}, {200, 200, 205}, {40, 120, 200}});
      bool clash = false;
      for (const Car& other : s.cars) clash |= cv::norm(other.poly[0] - car.poly[0]) < 2 * len + 2;
      if (!clash) s.cars.push_back(car);
    }
  }
  s.cars.insert(s.cars.end(), parked.begin(), parked.end());
  // Styles: cars move between the LiDAR and the photo flights. Some are only in the
  // photo, some only in the LiDAR, some moved along their lane.
  std::vector<Car> photo_cars = s.cars;
  if (styled) {
    std::vector<Car> depth_cars;
    photo_cars.clear();
    for (const Car& c : s.cars) {
      const double u = r.U();
      if (u < 0.2) {
        photo_cars.push_back(c);
      } else if (u < 0.4) {
        depth_cars.push_back(c);
      } else if (u < 0.55) {
        photo_cars.push_back(c);
        Car m = c;
        const cv::Point2d fwd = (c.poly[0] + c.poly[1] - c.poly[2] - c.poly[3]) * 0.5;
        const cv::Point2d d = fwd / std::max(1e-9, cv::norm(fwd)) * (r.U(6, 20) / o.res_m * (r.B(0.5) ? 1 : -1));
        for (auto& p : m.poly) p += d;
        depth_cars.push_back(m);
      } else {
        photo_cars.push_back(c), depth_cars.push_back(c);
      }
    }
    s.cars = depth_cars;
  }

  // ---- Depth raster.
  const Grid dg{-0.5, -0.5, 1, o.width, o.height};
  const Raster dr = RenderHeights(s, dg, false, true, r.Next());
  s.cars = photo_cars;
  city.building_id = cv::Mat1i(o.height, o.width, -1);
  city.tree_mask = cv::Mat1b(o.height, o.width, uchar(0));
  cv::RNG nrng(r.Next());
  const cv::Mat1f und = ValueNoise(cv::Size(o.width, o.height), 120 / o.res_m, nrng);
  const double ang = r.U(0, 2 * kPi);
  double slope = o.ground_slope * r.U(0.2, 1), und_amp = r.U(0.1, 0.5);
  cv::Mat1f und2;
  if (styled) {  // hilly: 1.6-4 % slope (default option) and undulations of metres
    slope = 4 * o.ground_slope * r.U(0.4, 1);
    und_amp = r.U(0.5, 2.5);
    und2 = ValueNoise(cv::Size(o.width, o.height), 40 / o.res_m, nrng);
  }
  double gmin = 1e18, gmax = -1e18;
  cv::Mat1f noise(o.height, o.width);
  nrng.fill(noise, cv::RNG::NORMAL, 0.f, float(o.depth_noise_m));
  city.depth = cv::Mat1f(o.height, o.width);
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      const double gz = slope * ((x - o.width / 2.0) * std::cos(ang) + (y - o.height / 2.0) * std::sin(ang)) * o.res_m +
                        und_amp * (und(y, x) - 0.5) * 2;
      const double g2 = und2.empty() ? 0.0 : 0.3 * und_amp * (und2(y, x) - 0.5) * 2;
      gmin = std::min(gmin, gz + g2), gmax = std::max(gmax, gz + g2);
      city.depth(y, x) = float(gz + g2 + dr.h(y, x) + noise(y, x));
      if (styled) {  // no return from water, few from dark roofs
        if (dr.cls(y, x) == kWater) city.depth(y, x) = std::numeric_limits<float>::quiet_NaN();
        const int bid = dr.id(y, x);
        if (bid >= 0 && dr.cls(y, x) == kRoof && s.b[size_t(bid)].nodata > 0 && r.U() < s.b[size_t(bid)].nodata)
          city.depth(y, x) = std::numeric_limits<float>::quiet_NaN();
      }
      const int id = dr.id(y, x);
      if (id >= 0 && id < s.counted) city.building_id(y, x) = id;
      if (dr.cls(y, x) == kTree) city.tree_mask(y, x) = 255;
    }
  if (styled) city.ground_range_m = gmax - gmin;
  // Missing returns in small patches.
  const long target = long(std::llround(o.missing_returns * double(o.width) * o.height));
  long missing = 0;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  while (missing < target) {
    const int cx = r.I(0, o.width - 1), cy = r.I(0, o.height - 1);
    const double rad = r.B(0.5) ? 0.5 : r.U(0.8, 3.2);
    const int ri = int(std::ceil(rad));
    for (int y = std::max(0, cy - ri); y <= std::min(o.height - 1, cy + ri) && missing < target; ++y)
      for (int x = std::max(0, cx - ri); x <= std::min(o.width - 1, cx + ri) && missing < target; ++x)
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= rad * rad + 0.25 && !std::isnan(city.depth(y, x)))
          city.depth(y, x) = nan, ++missing;
  }

  // ---- Orthophoto over the photo's footprint, then the photo.
  double f = std::clamp(1.0 / pg.scale, 1.0, 3.4);
  f = std::min(f, 3200.0 / std::max(fb.width, fb.height));
  const double margin = styled ? 6 + 45 * cv::norm(s.lean_px) : 6;  // roofs leaning in from outside
  const Grid og = GridOver(cv::Rect2d(fb.x - margin, fb.y - margin, fb.width + 2 * margin, fb.height + 2 * margin), f);
  cv::Mat1i oid;
  cv::Mat3b ortho = RenderOrtho(s, og, &oid);
  const double shrink = f * pg.scale;  // ortho pixels per photo pixel
  if (shrink > 1.2) cv::GaussianBlur(ortho, ortho, cv::Size(), 0.45 * std::sqrt(shrink * shrink - 1));
  const cv::Matx33d M = og.WorldToPix() * pg.H;  // photo -> ortho
  cv::warpPerspective(ortho, city.photo, M, pg.size, cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REFLECT);
  cv::Mat1f idf, pid;
  oid.convertTo(idf, CV_32F);
  cv::warpPerspective(idf, pid, M, pg.size, cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, cv::Scalar(-1));
  city.photo_building_id = cv::Mat1i(pg.size);
  for (int y = 0; y < pid.rows; ++y)
    for (int x = 0; x < pid.cols; ++x) {
      const int id = int(std::lround(pid(y, x)));
      city.photo_building_id(y, x) = id < 0 || id >= s.first_minor ? -1 : id < s.counted ? id : -2;
    }
  city.photo_road_mask = cv::Mat1b(pg.size, uchar(0));
  for (int y = 0; y < pg.size.height; ++y)
    for (int x = 0; x < pg.size.width; ++x) {
      const cv::Vec3d w = pg.H * cv::Vec3d(x, y, 1);
      if (OnRoad(s.lay.Query(w[0] / w[2], w[1] / w[2]), s.lay.sidewalk)) city.photo_road_mask(y, x) = 255;
    }
  SensorEffects(city.photo, r, o);

  // ---- Ground truth.
  city.photo_to_depth = pg.H;
  city.scale = pg.scale;
  city.rotation_deg = pg.rot_deg;
  city.perspective = pg.persp;
  city.sun_azimuth_deg = s.sun_az;
  city.sun_elevation_deg = s.sun_el;
  city.photo_overlap = PhotoOverlap(pg.H, pg.size, city.depth.size());
  {
    const int n = 64;
    int in = 0;
    const cv::Matx33d Hi = pg.H.inv();
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const cv::Vec3d p = Hi * cv::Vec3d((j + 0.5) * o.width / n - 0.5, (i + 0.5) * o.height / n - 0.5, 1);
        if (p[2] <= 0) continue;
        const double x = p[0] / p[2], y = p[1] / p[2];
        in += x >= -0.5 && y >= -0.5 && x < pg.size.width - 0.5 && y < pg.size.height - 0.5;
      }
    city.depth_overlap = double(in) / (n * n);
  }
  for (int i = 0; i < s.counted; ++i) {
    const Building& b = s.b[size_t(i)];
    std::vector<cv::Point2f> outer(b.outer.begin(), b.outer.end());
    city.corners.insert(city.corners.end(), outer.begin(), outer.end());
    city.footprints.push_back(outer);
    std::vector<std::vector<cv::Point2f>> hs;
    for (const auto& h : b.holes) hs.emplace_back(h.begin(), h.end());
    city.holes.push_back(hs);
    city.heights_m.push_back(b.eave_m);
    city.roofs.push_back(b.roof);
    city.shapes.push_back(b.shape);
    city.roof_colours.push_back(b.colour);
  }
  for (const Patch& p : s.patches) {
    if (p.kind != Patch::kWater) continue;
    cv::Point2d c(0, 0);
    for (const auto& q : p.poly) c += q * 0.25;
    if (c.x >= 0 && c.y >= 0 && c.x <= o.width - 1 && c.y <= o.height - 1)
      city.pools.emplace_back(std::vector<cv::Point2f>(p.poly.begin(), p.poly.end()));
  }
  return city;
}

void SaveCity(const City& c, const std::string& dir, const std::string& stem) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) throw Error(ErrorCode::kIo, dir + ": cannot create output directory");
  const std::string pre = stem.empty() ? "" : stem + "_";
  auto path = [&](const std::string& n) { return (fs::path(dir) / (pre + n)).string(); };
  auto write = [&](const std::string& p, const cv::Mat& m) {
    bool ok = false;
    try {
      ok = cv::imwrite(p, m);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (!ok) throw Error(ErrorCode::kIo, p + ": cannot write");
  };
  write(path("depth.tif"), c.depth);
  write(path("photo.png"), c.photo);
  // Preview: colour map over the valid range, no return black.
  {
    cv::Mat1b valid = (c.depth == c.depth);
    double lo = 0, hi = 1;
    cv::minMaxLoc(c.depth, &lo, &hi, nullptr, nullptr, valid);
    cv::Mat1b g;
    c.depth.convertTo(g, CV_8U, 255.0 / std::max(1e-6, hi - lo), -lo * 255.0 / std::max(1e-6, hi - lo));
    cv::Mat3b col;
    cv::applyColorMap(g, col, cv::COLORMAP_TURBO);
    col.setTo(cv::Scalar(0, 0, 0), ~valid);
    write(path("depth_preview.png"), col);
  }
  {
    cv::Mat1w ids(c.building_id.size());
    for (int y = 0; y < ids.rows; ++y)
      for (int x = 0; x < ids.cols; ++x) ids(y, x) = ushort(std::clamp(c.building_id(y, x) + 1, 0, 65535));
    write(path("building_id.png"), ids);
  }
  using nlohmann::json;
  auto pts = [](const std::vector<cv::Point2f>& v) {
    json a = json::array();
    for (const auto& p : v) a.push_back({p.x, p.y});
    return a;
  };
  json j;
  j["seed"] = c.seed;
  json H = json::array();
  for (int r = 0; r < 3; ++r) H.push_back({c.photo_to_depth(r, 0), c.photo_to_depth(r, 1), c.photo_to_depth(r, 2)});
  j["photo_to_depth"] = H;
  j["photo_to_depth_note"] = "3x3 homography, photo pixel -> depth pixel, pixel centres at integer coordinates";
  j["depth_size"] = {c.depth.cols, c.depth.rows};
  j["photo_size"] = {c.photo.cols, c.photo.rows};
  j["depth_units"] = "metres (DSM, ground ~0); NaN = no LiDAR return";
  j["res_m"] = c.options.res_m;
  j["scale"] = c.scale;
  j["rotation_deg"] = c.rotation_deg;
  j["perspective"] = {c.perspective.x, c.perspective.y};
  j["sun_azimuth_deg"] = c.sun_azimuth_deg;
  j["sun_elevation_deg"] = c.sun_elevation_deg;
  j["overlap"] = c.options.overlap;
  j["photo_overlap"] = c.photo_overlap;
  j["depth_overlap"] = c.depth_overlap;
  j["outside_buildings"] = c.outside_buildings;
  j["corners"] = pts(c.corners);
  json bs = json::array();
  for (size_t i = 0; i < c.footprints.size(); ++i) {
    json b;
    b["id"] = i;
    b["shape"] = c.shapes[i];
    b["roof"] = RoofTypeName(c.roofs[i]);
    b["height_m"] = c.heights_m[i];
    b["roof_bgr"] = {c.roof_colours[i][0], c.roof_colours[i][1], c.roof_colours[i][2]};
    b["footprint"] = pts(c.footprints[i]);
    json hs = json::array();
    for (const auto& h : c.holes[i]) hs.push_back(pts(h));
    b["holes"] = hs;
    bs.push_back(b);
  }
  j["buildings"] = bs;
  const CityOptions& o = c.options;
  j["options"] = {{"width", o.width}, {"height", o.height}, {"buildings", o.buildings}, {"res_m", o.res_m},
                  {"trees", o.trees}, {"min_scale", o.min_scale}, {"max_scale", o.max_scale},
                  {"max_perspective", o.max_perspective}, {"sun_azimuth_deg", o.sun_azimuth_deg},
                  {"sun_elevation_deg", o.sun_elevation_deg}, {"missing_returns", o.missing_returns},
                  {"depth_noise_m", o.depth_noise_m}, {"ground_slope", o.ground_slope},
                  {"photo_max_side", o.photo_max_side}, {"min_coverage", o.min_coverage},
                  {"max_coverage", o.max_coverage}, {"overlap", o.overlap}, {"pitched_roofs", o.pitched_roofs},
                  {"photo_blur", o.photo_blur}, {"photo_noise", o.photo_noise}};
  if (o.style != "classic") {  // classic truth.json stays as it was
    j["options"]["style"] = o.style;
    j["style"] = o.style;
    j["lean_m_per_m"] = {c.lean.x, c.lean.y};
    j["lean_note"] = "conventional orthophoto: a point h metres above the ground shows h * lean metres away (depth axes)";
    j["ground_range_m"] = c.ground_range_m;
    j["minor_structures"] = c.minor_structures;
    j["parking_lots"] = c.parking_lots;
    json pl = json::array();
    for (const auto& p : c.pools) pl.push_back(pts(p));
    j["pools"] = pl;
  }
  const std::string jp = path("truth.json");
  std::ofstream out(jp);
  out << j.dump(1) << "\n";
  if (!out) throw Error(ErrorCode::kIo, jp + ": cannot write");
}

}  // namespace mvkp
