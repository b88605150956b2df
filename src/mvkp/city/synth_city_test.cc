#include "mvkp/city/synth_city.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

bool SameBits(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), a.cols * a.elemSize()) != 0) return false;
  return true;
}

cv::Point2d Apply(const cv::Matx33d& H, cv::Point2d p) {
  const cv::Vec3d q = H * cv::Vec3d(p.x, p.y, 1);
  return {q[0] / q[2], q[1] / q[2]};
}

// Local scale and rotation of H at the photo centre, from finite differences.
void ScaleRotation(const City& c, double* scale, double* rot_deg) {
  const cv::Point2d pc((c.photo.cols - 1) / 2.0, (c.photo.rows - 1) / 2.0);
  const double e = 1e-3;
  const cv::Point2d o = Apply(c.photo_to_depth, pc);
  const cv::Point2d dx = (Apply(c.photo_to_depth, pc + cv::Point2d(e, 0)) - o) / e;
  const cv::Point2d dy = (Apply(c.photo_to_depth, pc + cv::Point2d(0, e)) - o) / e;
  *scale = std::sqrt(std::abs(dx.x * dy.y - dx.y * dy.x));
  *rot_deg = std::atan2(dx.y, dx.x) * 180 / CV_PI;
  if (*rot_deg < 0) *rot_deg += 360;
}

// Small, fast scenes for the many-seed geometry tests (geometry does not depend on content).
CityOptions Tiny() {
  CityOptions o;
  o.width = o.height = 200;
  o.buildings = 2;
  o.trees = 2;
  o.photo_max_side = 400;
  return o;
}

TEST(City, DeterministicForASeed) {
  CityOptions o;
  o.width = o.height = 400;
  o.buildings = 8;
  const City a = MakeCity(o, 7), b = MakeCity(o, 7), c = MakeCity(o, 8);
  EXPECT_TRUE(SameBits(a.depth, b.depth));
  EXPECT_TRUE(SameBits(a.photo, b.photo));
  EXPECT_TRUE(SameBits(a.building_id, b.building_id));
  EXPECT_EQ(a.photo_to_depth, b.photo_to_depth);
  EXPECT_EQ(a.corners, b.corners);
  EXPECT_NE(a.photo_to_depth, c.photo_to_depth);
  EXPECT_FALSE(SameBits(a.depth, c.depth));
}

TEST(City, HasTheRequestedBuildingsWithHeights) {
  const City c = MakeCity(CityOptions(), 3);
  ASSERT_EQ(c.footprints.size(), 30u);
  ASSERT_EQ(c.holes.size(), 30u);
  ASSERT_EQ(c.heights_m.size(), 30u);
  EXPECT_EQ(c.depth.size(), cv::Size(1000, 1000));
  size_t corners = 0;
  for (const auto& f : c.footprints) corners += f.size();
  EXPECT_EQ(c.corners.size(), corners);
  // Every building shows in the depth raster, higher than the ground around it.
  cv::Mat1b ground = (c.building_id < 0) & (c.tree_mask == 0) & (c.depth == c.depth);
  std::vector<float> g;
  for (int y = 0; y < c.depth.rows; y += 3)
    for (int x = 0; x < c.depth.cols; x += 3)
      if (ground(y, x)) g.push_back(c.depth(y, x));
  std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
  const double ground_med = g[g.size() / 2];
  EXPECT_LT(std::abs(ground_med), 3.0);
  for (int i = 0; i < 30; ++i) {
    const cv::Mat1b m = c.building_id == i;
    ASSERT_GT(cv::countNonZero(m), 20) << "building " << i;
    const cv::Mat1b valid = m & (c.depth == c.depth);
    EXPECT_GT(cv::mean(c.depth, valid)[0], ground_med + 2.0) << "building " << i;
    EXPECT_GE(c.heights_m[size_t(i)], 3.0);
    EXPECT_LE(c.heights_m[size_t(i)], 40.0);
    // The footprint polygon and the id raster agree.
    const cv::Rect bb = cv::boundingRect(c.footprints[size_t(i)]);
    const cv::Rect mb = cv::boundingRect(m);
    EXPECT_NEAR(bb.x, mb.x, 2); EXPECT_NEAR(bb.y, mb.y, 2);
    EXPECT_NEAR(bb.br().x, mb.br().x, 2); EXPECT_NEAR(bb.br().y, mb.br().y, 2);
  }
  CityOptions few;
  few.buildings = 7;
  EXPECT_EQ(MakeCity(few, 3).footprints.size(), 7u);
}

// The road mask covers the street grid (a share of the photo, dark asphalt
// or paving) and never a building.
TEST(City, RoadMaskCoversStreetsNotBuildings) {
  const City c = MakeCity(CityOptions(), 3);
  ASSERT_EQ(c.photo_road_mask.size(), c.photo.size());
  const double share = double(cv::countNonZero(c.photo_road_mask)) / double(c.photo.total());
  EXPECT_GT(share, 0.05);
  EXPECT_LT(share, 0.6);
  const cv::Mat1b on_building = c.photo_building_id != -1;
  EXPECT_LT(cv::countNonZero(on_building & c.photo_road_mask), 0.01 * cv::countNonZero(on_building));
}

TEST(City, VarietyOfShapesAndRoofs) {
  std::set<std::string> shapes;
  std::set<RoofType> roofs;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const City c = MakeCity(CityOptions(), seed);
    shapes.insert(c.shapes.begin(), c.shapes.end());
    roofs.insert(c.roofs.begin(), c.roofs.end());
  }
  for (const char* s : {"rect", "L", "T", "U", "courtyard", "irregular"}) EXPECT_TRUE(shapes.count(s)) << s;
  EXPECT_EQ(roofs.size(), 3u);
}

TEST(City, FootprintsLandOnRoofsInThePhoto) {
  int checked = 0, hits = 0;
  double d_own = 0, d_ground = 0;
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const City c = MakeCity(CityOptions(), seed);
    const cv::Matx33d Hi = c.photo_to_depth.inv();
    // Ground colour samples in the photo.
    std::vector<cv::Vec3b> ground;
    for (int y = 2; y < c.photo.rows; y += 17)
      for (int x = 2; x < c.photo.cols; x += 13)
        if (c.photo_building_id(y, x) == -1) ground.push_back(c.photo(y, x));
    ASSERT_FALSE(ground.empty());
    for (int i = 0; i < int(c.footprints.size()); ++i) {
      // A point deep inside the building: maximum of the distance transform.
      cv::Mat1b m = c.building_id == i;
      cv::Mat1f D;
      cv::distanceTransform(m, D, cv::DIST_L2, 3);
      cv::Point at;
      double dmax = 0;
      cv::minMaxLoc(D, nullptr, &dmax, nullptr, &at);
      const cv::Point2d p = Apply(Hi, cv::Point2d(at));
      const int px = int(std::lround(p.x)), py = int(std::lround(p.y));
      if (px < 3 || py < 3 || px >= c.photo.cols - 3 || py >= c.photo.rows - 3) continue;
      ++checked;
      hits += c.photo_building_id(py, px) == i;
      const cv::Vec3d roof = c.roof_colours[size_t(i)];
      d_own += cv::norm(cv::Vec3d(c.photo(py, px)) - roof, cv::NORM_L1);
      d_ground += cv::norm(cv::Vec3d(ground[size_t(i * 7919) % ground.size()]) - roof, cv::NORM_L1);
    }
  }
  ASSERT_GT(checked, 20);
  EXPECT_GE(hits, checked * 95 / 100);
  // Roof pixels look like their roofs (up to shading, shadows and sensor), not like the ground.
  EXPECT_LT(d_own, 0.5 * d_ground) << "own " << d_own / checked << " ground " << d_ground / checked;
}

TEST(City, FootprintOutlinesMatchThePhotoToAPixel) {
  int inside_ok = 0, outside_ok = 0, n = 0;
  for (std::uint64_t seed = 21; seed <= 24; ++seed) {
    const City c = MakeCity(CityOptions(), seed);
    const cv::Matx33d Hi = c.photo_to_depth.inv();
    const cv::Rect frame(4, 4, c.photo.cols - 8, c.photo.rows - 8);
    for (int i = 0; i < int(c.footprints.size()); ++i) {
      std::vector<cv::Point2f> poly;
      cv::perspectiveTransform(c.footprints[size_t(i)], poly, cv::Mat(Hi));
      for (size_t k = 0; k < poly.size(); ++k) {
        const cv::Point2f a = poly[k], b = poly[(k + 1) % poly.size()];
        const double len = cv::norm(b - a);
        if (len < 8) continue;
        const cv::Point2f m = (a + b) * 0.5f, nrm(-(b - a).y / float(len), (b - a).x / float(len));
        cv::Point2f in = m + 2.f * nrm, out = m - 2.f * nrm;
        if (cv::pointPolygonTest(poly, in, false) < 0) std::swap(in, out);
        if (!frame.contains(cv::Point(in)) || !frame.contains(cv::Point(out))) continue;
        ++n;
        inside_ok += c.photo_building_id(cv::Point(std::lround(in.x), std::lround(in.y))) == i;
        outside_ok += c.photo_building_id(cv::Point(std::lround(out.x), std::lround(out.y))) != i;
      }
    }
  }
  ASSERT_GT(n, 50);
  EXPECT_GE(inside_ok, n * 9 / 10);
  EXPECT_GE(outside_ok, n * 95 / 100);
}

TEST(City, ScaleRotationAndPerspectiveCoverTheirRanges) {
  const CityOptions o = Tiny();
  double smin = 1e9, smax = 0;
  int bins[8] = {0};
  for (std::uint64_t seed = 1; seed <= 150; ++seed) {
    const City c = MakeCity(o, seed);
    double s, r;
    ScaleRotation(c, &s, &r);
    EXPECT_NEAR(s, c.scale, 1e-3 * c.scale);
    EXPECT_GE(s, 0.3 - 1e-6);
    EXPECT_LE(s, 3.0 + 1e-6);
    smin = std::min(smin, s), smax = std::max(smax, s);
    EXPECT_NEAR(std::cos((r - c.rotation_deg) * CV_PI / 180), 1.0, 1e-6);
    ++bins[std::min(7, int(r / 45))];
    // Mild perspective: the projective divisor varies by at most max_perspective over the photo.
    const cv::Matx33d& H = c.photo_to_depth;
    const double pcx = (c.photo.cols - 1) / 2.0, pcy = (c.photo.rows - 1) / 2.0;
    const double wc = H(2, 0) * pcx + H(2, 1) * pcy + H(2, 2);
    for (double x : {-0.5, c.photo.cols - 0.5})
      for (double y : {-0.5, c.photo.rows - 0.5}) {
        const double w = (H(2, 0) * x + H(2, 1) * y + H(2, 2)) / wc;
        EXPECT_GE(w, 1 - o.max_perspective - 1e-3);
        EXPECT_LE(w, 1 + o.max_perspective + 1e-3);
      }
  }
  EXPECT_LT(smin, 0.4);
  EXPECT_GT(smax, 2.4);
  for (int b = 0; b < 8; ++b) EXPECT_GT(bins[b], 3) << "rotation bin " << b;  // full circle, upside down included
}

TEST(City, MissingReturnsMatchTheOption) {
  for (double m : {0.0, 0.01, 0.05}) {
    CityOptions o;
    o.width = o.height = 500;
    o.buildings = 8;
    o.missing_returns = m;
    const City c = MakeCity(o, 5);
    const double frac = 1.0 - double(cv::countNonZero(c.depth == c.depth)) / c.depth.total();
    EXPECT_NEAR(frac, m, 0.001) << m;
  }
}

TEST(City, TreesAreNoisyInDepthAndRoofsAreNot) {
  const City c = MakeCity(CityOptions(), 9);
  double tree = 0, roof = 0;
  int nt = 0, nr = 0;
  for (int y = 0; y < c.depth.rows; ++y)
    for (int x = 0; x + 1 < c.depth.cols; ++x) {
      const float a = c.depth(y, x), b = c.depth(y, x + 1);
      if (std::isnan(a) || std::isnan(b)) continue;
      if (c.tree_mask(y, x) && c.tree_mask(y, x + 1)) tree += std::abs(a - b), ++nt;
      const int id = c.building_id(y, x);
      if (id >= 0 && c.building_id(y, x + 1) == id && c.roofs[size_t(id)] == RoofType::kFlat) roof += std::abs(a - b), ++nr;
    }
  ASSERT_GT(nt, 1000);
  ASSERT_GT(nr, 1000);
  EXPECT_GT(tree / nt, 1.0);
  EXPECT_LT(roof / nr, 0.3);
}

TEST(City, NoOverlapOptionReallyHasNoOverlap) {
  CityOptions o = Tiny();
  o.width = o.height = 400;
  o.buildings = 6;
  o.overlap = false;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const City c = MakeCity(o, seed);
    EXPECT_EQ(c.photo_overlap, 0.0);
    EXPECT_EQ(c.depth_overlap, 0.0);
    std::vector<cv::Point2f> quad, rect{{-0.5f, -0.5f}, {399.5f, -0.5f}, {399.5f, 399.5f}, {-0.5f, 399.5f}}, inter;
    for (cv::Point2d p : {cv::Point2d(-0.5, -0.5), cv::Point2d(c.photo.cols - 0.5, -0.5),
                          cv::Point2d(c.photo.cols - 0.5, c.photo.rows - 0.5), cv::Point2d(-0.5, c.photo.rows - 0.5)})
      quad.push_back(cv::Point2f(Apply(c.photo_to_depth, p)));
    EXPECT_NEAR(cv::intersectConvexConvex(quad, rect, inter), 0.0, 1e-6) << "seed " << seed;
    double lo = 0, hi = 0;
    cv::minMaxLoc(c.photo_building_id, &lo, &hi);
    EXPECT_LT(hi, 0) << "a depth building shows in a no-overlap photo, seed " << seed;
    // The photo is still a city, not an empty field.
    cv::Scalar mean, sd;
    cv::meanStdDev(c.photo, mean, sd);
    EXPECT_GT(sd[1], 10);
  }
  o.overlap = true;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) EXPECT_GT(MakeCity(o, seed).photo_overlap, 0.15);
}

TEST(City, SaveWritesReadableFiles) {
  CityOptions o;
  o.width = o.height = 300;
  o.buildings = 5;
  o.missing_returns = 0.02;
  const City c = MakeCity(o, 11);
  const auto dir = std::filesystem::temp_directory_path() / ("mvkp_city_test_" + std::to_string(::getpid()));
  SaveCity(c, dir.string(), "");
  const cv::Mat d = cv::imread((dir / "depth.tif").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(d.type(), CV_32FC1);
  EXPECT_TRUE(SameBits(d, c.depth));  // NaN included
  const cv::Mat p = cv::imread((dir / "photo.png").string(), cv::IMREAD_COLOR);
  EXPECT_TRUE(SameBits(p, c.photo));
  const cv::Mat prev = cv::imread((dir / "depth_preview.png").string(), cv::IMREAD_COLOR);
  EXPECT_EQ(prev.size(), c.depth.size());
  const cv::Mat ids = cv::imread((dir / "building_id.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(ids.type(), CV_16UC1);
  EXPECT_EQ(cv::countNonZero(ids == 3), cv::countNonZero(c.building_id == 2));
  std::ifstream in(dir / "truth.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(j["photo_to_depth"][r][k].get<double>(), c.photo_to_depth(r, k));
  EXPECT_EQ(j["seed"].get<std::uint64_t>(), 11u);
  EXPECT_EQ(j["buildings"].size(), c.footprints.size());
  EXPECT_EQ(j["corners"].size(), c.corners.size());
  EXPECT_EQ(j["options"]["buildings"].get<int>(), 5);
  SaveCity(c, dir.string(), "x");
  EXPECT_TRUE(std::filesystem::exists(dir / "x_truth.json"));
  // An output "directory" below a regular file cannot be created.
  EXPECT_THROW(SaveCity(c, (dir / "x_truth.json" / "sub").string(), ""), Error);
  std::filesystem::remove_all(dir);
}

TEST(City, BadOptionsAreRejected) {
  CityOptions o;
  o.min_scale = 0;
  EXPECT_THROW(MakeCity(o, 1), Error);
  o = CityOptions();
  o.width = 10;
  EXPECT_THROW(MakeCity(o, 1), Error);
  o = CityOptions();
  o.missing_returns = 0.9;
  EXPECT_THROW(MakeCity(o, 1), Error);
  o = CityOptions();
  o.max_scale = 0.2;
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace mvkp
