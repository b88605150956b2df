#include "mvkp/shapes/register.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

using Poly = std::vector<cv::Point2f>;

Contour Densify(const Poly& poly, double step) {
  Contour out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const cv::Point2f a = poly[i], b = poly[(i + 1) % poly.size()];
    const int n = std::max(1, int(std::ceil(cv::norm(b - a) / step)));
    for (int k = 0; k < n; ++k) out.push_back(a + (b - a) * (float(k) / n));
  }
  return out;
}

// A building footprint around the origin: rectangle, L, T, U or irregular.
Poly Footprint(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0, 1);
  const float w = float(30 + 70 * U(rng)), h = float(30 + 70 * U(rng));
  const float a = float(0.3 + 0.4 * U(rng)), b = float(0.3 + 0.4 * U(rng));
  Poly p;
  switch (int(U(rng) * 5)) {
    case 0: p = {{0, 0}, {w, 0}, {w, h}, {0, h}}; break;
    case 1: p = {{0, 0}, {w, 0}, {w, a * h}, {b * w, a * h}, {b * w, h}, {0, h}}; break;
    case 2: {  // T
      const float l = w * (0.5f - b / 2), r = w * (0.5f + b / 2);
      p = {{0, 0}, {w, 0}, {w, a * h}, {r, a * h}, {r, h}, {l, h}, {l, a * h}, {0, a * h}};
      break;
    }
    case 3: {  // U
      const float l = w * (0.5f - b / 3), r = w * (0.5f + b / 3);
      p = {{0, 0}, {w, 0}, {w, h}, {r, h}, {r, a * h}, {l, a * h}, {l, h}, {0, h}};
      break;
    }
    default: {  // irregular: star-shaped polygon with 5-9 vertices
      const int n = 5 + int(U(rng) * 5);
      for (int i = 0; i < n; ++i) {
        const double t = 2 * CV_PI * (i + 0.3 * U(rng)) / n, r = 0.5 * std::max(w, h) * (0.55 + 0.45 * U(rng));
        p.emplace_back(float(r * std::cos(t)), float(r * std::sin(t)));
      }
    }
  }
  cv::Point2f c(0, 0);
  for (const auto& q : p) c += q;
  c *= 1.0f / float(p.size());
  for (auto& q : p) q -= c;
  return p;
}

Poly Place(const Poly& p, double deg, cv::Point2f t) {
  const double r = deg * CV_PI / 180, c = std::cos(r), s = std::sin(r);
  Poly out;
  for (const auto& q : p) out.emplace_back(float(c * q.x - s * q.y + t.x), float(s * q.x + c * q.y + t.y));
  return out;
}

// ~30 footprints on a jittered 6 x 5 grid of 160 px cells (depth pixels).
std::vector<Poly> City(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0, 1);
  const double city_angle = 360 * U(rng);
  std::vector<Poly> out;
  for (int gy = 0; gy < 5; ++gy)
    for (int gx = 0; gx < 6; ++gx) {
      const double ang = U(rng) < 0.7 ? city_angle + 3 * (U(rng) - 0.5) : 360 * U(rng);
      out.push_back(Place(Footprint(rng), ang,
                          {float(100 + 160 * gx + 20 * (U(rng) - 0.5)), float(100 + 160 * gy + 20 * (U(rng) - 0.5))}));
    }
  return out;
}

Poly Blob(std::mt19937_64& rng, cv::Point2f c, double size) {
  std::uniform_real_distribution<double> U(0, 1);
  const int n = 6 + int(U(rng) * 8);
  Poly p;
  for (int i = 0; i < n; ++i) {
    const double t = 2 * CV_PI * i / n, r = size * (0.4 + 0.6 * U(rng));
    p.emplace_back(float(c.x + r * std::cos(t)), float(c.y + r * std::sin(t)));
  }
  return p;
}

// Sutherland-Hodgman clip of a polygon against the half-plane n . (x - c) >= 0.
Poly ClipHalfPlane(const Poly& p, cv::Point2f c, cv::Point2f n) {
  Poly out;
  for (size_t i = 0; i < p.size(); ++i) {
    const cv::Point2f a = p[i], b = p[(i + 1) % p.size()];
    const float da = n.dot(a - c), db = n.dot(b - c);
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

struct Scene {
  std::vector<Contour> photo, depth;
  cv::Matx33d depth_to_photo;              // ground truth (noise-free)
  std::vector<cv::Point2f> depth_corners;  // corners of buildings seen in both images
};

// The photo shows the footprints of `city` (or of another city when
// photo_city != nullptr) mapped by a random similarity (any rotation, scale
// 0.3-3) + mild perspective, inside a random window; 20 % of the buildings
// are missed on each side, 15 % false regions are added on each side, the
// photo contours get a few px of noise.
Scene MakeScene(std::uint64_t seed, bool other_city = false, double split = 0.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::normal_distribution<double> N(0, 1);
  const std::vector<Poly> city = City(rng);
  std::mt19937_64 rng2(seed * 7919 + 17);
  const std::vector<Poly> photo_city = other_city ? City(rng2) : city;
  Scene sc;
  // ground truth depth -> photo
  const double ang = 2 * CV_PI * U(rng), scale = std::exp(std::log(0.3) + U(rng) * std::log(10.0));
  const double c = std::cos(ang) * scale, s = std::sin(ang) * scale;
  const cv::Matx33d S(c, -s, 0, s, c, 0, 0, 0, 1);
  // mild perspective: up to ~+-6 % scale change across the ~1000 px city
  const double px = (U(rng) - 0.5) * 1.2e-4, py = (U(rng) - 0.5) * 1.2e-4;
  const cv::Matx33d Pm(1, 0, 0, 0, 1, 0, px, py, 1);
  const cv::Matx33d C(1, 0, -530, 0, 1, -450, 0, 0, 1);  // about the city centre
  cv::Matx33d G = S * Pm * C;
  // photo window: a random 55-100 % part of the mapped city, per axis
  Poly all;
  for (const auto& p : photo_city) { const Poly q = TransformPoints(G, p); all.insert(all.end(), q.begin(), q.end()); }
  const cv::Rect2f bb = cv::boundingRect(all);
  const float fw = float(0.55 + 0.45 * U(rng)), fh = float(0.55 + 0.45 * U(rng));
  const cv::Rect2f win(bb.x + float(U(rng)) * bb.width * (1 - fw), bb.y + float(U(rng)) * bb.height * (1 - fh),
                       bb.width * fw, bb.height * fh);
  G = cv::Matx33d(1, 0, -win.x + 5, 0, 1, -win.y + 5, 0, 0, 1) * G;  // photo px: window origin near 0
  sc.depth_to_photo = G;
  const double noise_px = 1.5;
  for (size_t i = 0; i < city.size(); ++i) {
    const bool in_depth = U(rng) >= 0.2, in_photo = U(rng) >= 0.2;
    if (in_depth) {
      Contour d = Densify(city[i], 1.0);
      for (auto& q : d) q += cv::Point2f(float(0.3 * N(rng)), float(0.3 * N(rng)));
      sc.depth.push_back(d);
    }
    Poly q = TransformPoints(G, photo_city[i]);
    bool inside = true;
    for (const auto& v : q) inside = inside && v.x >= 5 && v.y >= 5 && v.x < win.width + 5 && v.y < win.height + 5;
    if (!inside || !in_photo) continue;
    if (split > 0 && U(rng) < split) {  // over-segmentation: keep one side of a cut through the centroid
      cv::Point2f m(0, 0);
      for (const auto& v : q) m += v;
      m *= 1.0f / float(q.size());
      const double a = 2 * CV_PI * U(rng);
      q = ClipHalfPlane(q, m, {float(std::cos(a)), float(std::sin(a))});
      if (q.size() < 3) continue;
    }
    for (auto& v : q) v += cv::Point2f(float(noise_px * N(rng)), float(noise_px * N(rng)));  // corner noise
    Contour pc = Densify(q, 1.0);
    for (auto& v : pc) v += cv::Point2f(float(0.5 * noise_px * N(rng)), float(0.5 * noise_px * N(rng)));
    sc.photo.push_back(pc);
    if (in_depth && !other_city) sc.depth_corners.insert(sc.depth_corners.end(), city[i].begin(), city[i].end());
  }
  // false regions: 15 % on each side
  const int nf = int(std::lround(0.15 * city.size()));
  for (int k = 0; k < nf; ++k) {
    sc.depth.push_back(Densify(Blob(rng, {float(60 + 900 * U(rng)), float(60 + 750 * U(rng))}, 15 + 35 * U(rng)), 1.0));
    sc.photo.push_back(Densify(Blob(rng, {float(5 + win.width * U(rng)), float(5 + win.height * U(rng))},
                                    (15 + 35 * U(rng)) * scale), 1.0));
  }
  // shuffle both sides (no index correspondence)
  std::shuffle(sc.photo.begin(), sc.photo.end(), rng);
  std::shuffle(sc.depth.begin(), sc.depth.end(), rng);
  return sc;
}

double CornerError(const Scene& sc, const cv::Matx33d& photo_to_depth) {
  if (sc.depth_corners.empty()) return 0;
  const Contour in_photo = TransformPoints(sc.depth_to_photo, sc.depth_corners);
  const Contour back = TransformPoints(photo_to_depth, in_photo);
  double e = 0;
  for (size_t i = 0; i < back.size(); ++i) e += cv::norm(back[i] - sc.depth_corners[i]);
  return e / double(back.size());
}

TEST(Register, EmptyInputsAreRejectedWithAReason) {
  const Contour sq = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  for (const auto& [p, d] : std::vector<std::pair<std::vector<Contour>, std::vector<Contour>>>{
           {{}, {}}, {{sq}, {}}, {{}, {sq}}, {{Contour{{0, 0}, {1, 1}}}, {sq}}, {{sq, sq}, {sq, sq}}}) {
    const Registration r = RegisterContours(p, d);
    EXPECT_FALSE(r.ok);
    EXPECT_EQ(r.reason.rfind("no registration found", 0), 0u) << r.reason;
  }
  RegistrationOptions bad;
  bad.inlier_px = 0;
  EXPECT_THROW(RegisterContours({sq}, {sq}, bad), Error);
}

TEST(Register, SyntheticCities) {
  const int trials = 50;
  int ok = 0, success = 0;
  double ape_sum = 0, ms_sum = 0, ms_max = 0;
  int models[3] = {0, 0, 0};
  for (int t = 0; t < trials; ++t) {
    const Scene sc = MakeScene(1000 + t);
    RegistrationOptions opt;
    const Registration r = RegisterContours(sc.photo, sc.depth, opt);
    const double ms = r.match_ms + r.propagate_ms;
    ms_sum += ms, ms_max = std::max(ms_max, ms);
    if (!r.ok) {
      std::printf("trial %2d: %zu photo / %zu depth regions: %s (%.0f ms)\n", t, sc.photo.size(), sc.depth.size(),
                  r.reason.c_str(), ms);
      continue;
    }
    ++ok;
    const double err = CornerError(sc, r.photo_to_depth);
    models[r.model == "similarity" ? 0 : r.model == "affine" ? 1 : 2]++;
    if (err <= 5.0) ++success, ape_sum += err;
    else
      std::printf("trial %2d: WRONG (corner error %.1f px): %s\n", t, err, r.reason.c_str());
    EXPECT_FALSE(r.correspondences.empty());
    EXPECT_GE(int(r.region_matches.size()), opt.min_regions);
  }
  const double ape = success ? ape_sum / success : 0;
  std::printf("synthetic cities: %d/%d registered, %d/%d correct (<= 5 px), APE %.2f px, "
              "models sim/aff/persp %d/%d/%d, %.0f ms mean, %.0f ms max\n",
              ok, trials, success, trials, ape, models[0], models[1], models[2], ms_sum / trials, ms_max);
  EXPECT_GE(success, int(0.8 * trials));
  EXPECT_LE(ape, 3.0);
  EXPECT_LE(ok - success, trials / 20) << "wrong transforms reported as success";
  // The time is printed, not asserted: on a shared machine (CI runs two
  // tests at once) the mean reached 1.9 s here while other jobs ran. The
  // speed goal lives in scripts/aerial_eval.py's median time per scene.
}

TEST(Register, AStretchedPhotoIsNotANadirPhoto) {
  // The same scenes with the photo stretched 1.3x along one axis: no nadir
  // photo of flat ground looks like that (square pixels seen from above),
  // so the default refuses what max_anisotropy = 0 accepts.
  int accepted_off = 0, accepted_on = 0, refused_for_it = 0;
  for (int t = 0; t < 12; ++t) {
    Scene sc = MakeScene(1000 + t);
    for (auto& c : sc.photo)
      for (auto& q : c) q.x *= 1.3f;
    RegistrationOptions off;
    off.max_anisotropy = 0;
    const Registration a = RegisterContours(sc.photo, sc.depth, off);
    const Registration b = RegisterContours(sc.photo, sc.depth);
    accepted_off += a.ok, accepted_on += b.ok;
    refused_for_it += !b.ok && b.reason.find("stretches the photo") != std::string::npos;
    if (a.ok) std::printf("trial %d, stretched: %s\n", t, b.ok ? "registered" : b.reason.c_str());
  }
  EXPECT_GE(accepted_off, 3);
  EXPECT_EQ(accepted_on, 0);
  EXPECT_GE(refused_for_it, 3);
  RegistrationOptions bad;
  bad.max_anisotropy = 0.5;
  EXPECT_THROW(bad.Check(), Error);
  RegistrationOptions bad_gain;
  bad_gain.joint_lean_gain = -0.1;
  EXPECT_THROW(bad_gain.Check(), Error);
}

TEST(Register, DifferentCityIsRejected) {
  const int trials = 40;
  int rejected = 0;
  double ms_sum = 0;
  for (int t = 0; t < trials; ++t) {
    const Scene sc = MakeScene(5000 + t, /*other_city=*/true);
    const Registration r = RegisterContours(sc.photo, sc.depth);
    ms_sum += r.match_ms + r.propagate_ms;
    if (!r.ok) ++rejected;
    else std::printf("trial %2d: false registration: %s\n", t, r.reason.c_str());
  }
  std::printf("different city: %d/%d rejected, %.0f ms mean\n", rejected, trials, ms_sum / trials);
  EXPECT_GE(rejected, int(std::ceil(0.95 * trials)));
}

TEST(Register, OverSegmentedPhotoRegions) {
  // 20 % of the photo buildings are cut in half (one side of a random cut
  // through the centroid is kept)
  const int trials = 20;
  int success = 0;
  for (int t = 0; t < trials; ++t) {
    const Scene sc = MakeScene(3000 + t, false, 0.2);
    const Registration r = RegisterContours(sc.photo, sc.depth);
    if (r.ok && CornerError(sc, r.photo_to_depth) <= 5.0) ++success;
    else if (r.ok) ADD_FAILURE() << "trial " << t << ": wrong transform reported: " << r.reason;
  }
  std::printf("over-segmented photo regions: %d/%d correct\n", success, trials);
  EXPECT_GE(success, int(0.8 * trials));
}

TEST(Register, PrincipalDirectionSpeedUpWithFallback) {
  const int trials = 12;
  int success = 0, used = 0, hyps_on = 0, hyps_off = 0;
  for (int t = 0; t < trials; ++t) {
    const Scene sc = MakeScene(4000 + t);
    RegistrationOptions on;
    on.use_principal_directions = true;
    const Registration r = RegisterContours(sc.photo, sc.depth, on);
    const Registration r0 = RegisterContours(sc.photo, sc.depth);
    hyps_on += r.hypotheses, hyps_off += r0.hypotheses;
    if (r.ok && CornerError(sc, r.photo_to_depth) <= 5.0) ++success;
    used += r.used_principal_directions;
  }
  std::printf("principal directions: %d/%d correct, restricted search used in %d, hypotheses %d vs %d without\n",
              success, trials, used, hyps_on, hyps_off);
  EXPECT_GE(success, int(0.8 * trials));
  EXPECT_GT(used, 0);
  // a different city: the restricted pass finds nothing, the fallback neither
  RegistrationOptions on;
  on.use_principal_directions = true;
  const Scene other = MakeScene(6001, true);
  EXPECT_FALSE(RegisterContours(other.photo, other.depth, on).ok);
}

TEST(Register, DeterministicAndModelChoice) {
  const Scene sc = MakeScene(77);
  const Registration a = RegisterContours(sc.photo, sc.depth), b = RegisterContours(sc.photo, sc.depth);
  ASSERT_EQ(a.ok, b.ok);
  if (a.ok) {
    EXPECT_EQ(a.photo_to_depth, b.photo_to_depth);
    EXPECT_EQ(a.model, b.model);
  }
  for (auto m : {RegistrationOptions::Model::kSimilarity, RegistrationOptions::Model::kAffine,
                 RegistrationOptions::Model::kPerspective}) {
    RegistrationOptions o;
    o.model = m;
    const Registration r = RegisterContours(sc.photo, sc.depth, o);
    if (!r.ok) continue;
    EXPECT_EQ(r.model, m == RegistrationOptions::Model::kSimilarity ? "similarity"
                       : m == RegistrationOptions::Model::kAffine  ? "affine"
                                                                   : "perspective");
    EXPECT_LT(CornerError(sc, r.photo_to_depth), 8.0);
  }
}

TEST(Register, PrincipalDirections) {
  // a grid city rotated by 30 degrees has principal directions 30 / 120
  std::vector<Contour> regions;
  for (int i = 0; i < 12; ++i)
    regions.push_back(Densify(Place({{-30, -20}, {30, -20}, {30, 20}, {-30, 20}}, 30, {float(100 * (i % 4)), float(100 * (i / 4))}), 1.0));
  const auto pd = DetectPrincipalDirections(regions);
  ASSERT_TRUE(pd.has_value());
  auto close = [](double a, double b) { double d = std::fmod(std::abs(a - b), 180.0); return std::min(d, 180 - d) < 4; };
  EXPECT_TRUE(close(pd->first_deg, 30) || close(pd->first_deg, 120)) << pd->first_deg;
  EXPECT_TRUE(close(pd->second_deg, 30) || close(pd->second_deg, 120)) << pd->second_deg;
  // irregular blobs: no distinct directions
  std::mt19937_64 rng(5);
  std::vector<Contour> blobs;
  for (int i = 0; i < 10; ++i) blobs.push_back(Densify(Blob(rng, {float(100 * i), 0}, 40), 1.0));
  (void)DetectPrincipalDirections(blobs);  // may or may not find peaks; must not crash
  EXPECT_FALSE(DetectPrincipalDirections(cv::Mat()).has_value());
}

}  // namespace
}  // namespace mvkp
