#include "mvkp/cdikp/cdikp.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

cv::Mat LoadSample(const std::string& name, int flags = cv::IMREAD_GRAYSCALE) {
  const cv::Mat m = cv::imread(std::string(MVKP_SOURCE_DIR) + "/samples/" + name, flags);
  EXPECT_FALSE(m.empty()) << name;
  return m;
}

// A similarity that rotates by deg (clockwise on screen, i.e. towards +y in
// image coordinates) and scales by s about the image centre, with a canvas
// that holds the whole result. Returns the 3x3 homography; fills out.
cv::Mat Warp(const cv::Mat& img, double deg, double s, cv::Mat& out) {
  const double a = deg * CV_PI / 180.0, c = std::cos(a) * s, sn = std::sin(a) * s;
  const double w = img.cols, h = img.rows;
  const double ow = std::abs(c) * w + std::abs(sn) * h, oh = std::abs(sn) * w + std::abs(c) * h;
  const double cx = (w - 1) / 2, cy = (h - 1) / 2, ocx = (ow - 1) / 2, ocy = (oh - 1) / 2;
  cv::Mat A = (cv::Mat_<double>(2, 3) << c, -sn, ocx - (c * cx - sn * cy), sn, c, ocy - (sn * cx + c * cy));
  cv::warpAffine(img, out, A, cv::Size(int(std::ceil(ow)), int(std::ceil(oh))), cv::INTER_LINEAR,
                 cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::Mat H = cv::Mat::eye(3, 3, CV_64F);
  A.copyTo(H.rowRange(0, 2));
  return H;
}

cv::Point2f Apply(const cv::Mat& H, cv::Point2f p) {
  const double* h = H.ptr<double>(0);
  const double z = h[6] * p.x + h[7] * p.y + h[8];
  return {float((h[0] * p.x + h[1] * p.y + h[2]) / z), float((h[3] * p.x + h[4] * p.y + h[5]) / z)};
}

// Maximum distance between the image corners mapped by H and by H_true.
double CornerError(const cv::Mat& H, const cv::Mat& H_true, cv::Size size) {
  double worst = 0;
  for (cv::Point2f p : {cv::Point2f(0, 0), cv::Point2f(float(size.width - 1), 0),
                        cv::Point2f(0, float(size.height - 1)),
                        cv::Point2f(float(size.width - 1), float(size.height - 1))}) {
    worst = std::max(worst, double(cv::norm(Apply(H, p) - Apply(H_true, p))));
  }
  return worst;
}

struct PairResult {
  int good = 0, inliers = 0;
  double corner_error = 1e9;
};

// Used only through cv::Feature2D / cv::BFMatcher / cv::findHomography.
PairResult MatchPair(const cv::Ptr<cv::Feature2D>& f, const cv::Mat& a, const cv::Mat& b, const cv::Mat& H_true) {
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  f->detectAndCompute(a, cv::noArray(), ka, da);
  f->detectAndCompute(b, cv::noArray(), kb, db);
  PairResult r;
  if (da.empty() || db.empty()) return r;
  cv::BFMatcher matcher(f->defaultNorm());
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(da, db, knn, 2);
  std::vector<cv::Point2f> pa, pb;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      pa.push_back(ka[m[0].queryIdx].pt);
      pb.push_back(kb[m[0].trainIdx].pt);
    }
  r.good = int(pa.size());
  if (pa.size() < 4) return r;
  cv::Mat inl;
  const cv::Mat H = cv::findHomography(pa, pb, cv::RANSAC, 3.0, inl);
  if (H.empty()) return r;
  r.inliers = cv::countNonZero(inl);
  r.corner_error = CornerError(H, H_true, a.size());
  return r;
}

TEST(Cdikp, Feature2DInterface) {
  const cv::Ptr<cv::Feature2D> f = CDIKP::create();
  EXPECT_EQ(f->descriptorSize(), 20);
  EXPECT_EQ(f->descriptorType(), CV_32F);
  EXPECT_EQ(f->defaultNorm(), cv::NORM_L2);
  EXPECT_EQ(f->getDefaultName(), "Feature2D.CDIKP");
  EXPECT_FALSE(f->empty());
}

struct Geometry {
  double deg, scale;
};

class CdikpHomography : public ::testing::TestWithParam<Geometry> {};

TEST_P(CdikpHomography, RecoversSyntheticSimilarity) {
  const Geometry g = GetParam();
  const cv::Ptr<cv::Feature2D> f = CDIKP::create();
  for (const char* name : {"starry_night.jpg", "building.jpg"}) {
    const cv::Mat img = LoadSample(name, cv::IMREAD_COLOR);  // BGR in: converted inside
    cv::Mat warped;
    const cv::Mat H_true = Warp(img, g.deg, g.scale, warped);
    const PairResult r = MatchPair(f, img, warped, H_true);
    EXPECT_LT(r.corner_error, 3.0) << name << " rot " << g.deg << " scale " << g.scale << ": " << r.good
                                   << " ratio matches, " << r.inliers << " inliers";
    EXPECT_GE(r.inliers, 15) << name;
  }
}

INSTANTIATE_TEST_SUITE_P(Synthetic, CdikpHomography,
                         ::testing::Values(Geometry{30, 1.0}, Geometry{90, 1.0}, Geometry{0, 0.7},
                                           Geometry{0, 1.5}, Geometry{-45, 0.7}, Geometry{120, 1.5}));

// Fraction of keypoints whose descriptor in `a` is nearer its own counterpart
// in `b` than to at least 95 % of the other descriptors in `b`.
double NearestFraction(const cv::Mat& a, const cv::Mat& b) {
  int ok = 0;
  for (int i = 0; i < a.rows; ++i) {
    const double own = cv::norm(a.row(i), b.row(i), cv::NORM_L2);
    int closer = 0;
    for (int j = 0; j < b.rows; ++j)
      if (j != i && cv::norm(a.row(i), b.row(j), cv::NORM_L2) <= own) ++closer;
    if (closer <= 0.05 * (b.rows - 1)) ++ok;
  }
  return double(ok) / a.rows;
}

// The same physical points, described in the original and in a rotated (and
// scaled) copy with keypoints carried over by the known transform. The
// rotation direction matters: carrying the angle the wrong way round fails.
TEST(Cdikp, SamePointSameDescriptorUnderRotation) {
  const cv::Mat img = LoadSample("starry_night.jpg");
  const cv::Ptr<CDIKP> f = CDIKP::create();
  std::vector<cv::KeyPoint> kps;
  f->detect(img, kps);
  ASSERT_GT(kps.size(), 100u);
  cv::Mat d0;
  f->compute(img, kps, d0);
  for (Geometry g : {Geometry{30, 1.0}, Geometry{90, 1.0}, Geometry{-60, 1.3}}) {
    cv::Mat warped;
    const cv::Mat H = Warp(img, g.deg, g.scale, warped);
    std::vector<cv::KeyPoint> moved = kps, wrong = kps;
    for (std::size_t i = 0; i < kps.size(); ++i) {
      moved[i].pt = wrong[i].pt = Apply(H, kps[i].pt);
      moved[i].size = wrong[i].size = float(kps[i].size * g.scale);
      moved[i].angle = float(std::fmod(kps[i].angle + g.deg + 720.0, 360.0));
      wrong[i].angle = float(std::fmod(kps[i].angle - g.deg + 720.0, 360.0));
    }
    cv::Mat d1, dw;
    f->compute(warped, moved, d1);
    f->compute(warped, wrong, dw);
    ASSERT_EQ(d1.rows, d0.rows);
    const double right = NearestFraction(d0, d1), bad = NearestFraction(d0, dw);
    EXPECT_GT(right, 0.9) << "rot " << g.deg;
    EXPECT_LT(bad, 0.5) << "rot " << g.deg;
  }
}

// An exact 90-degree rotation (no interpolation): the canonical patch of the
// rotated keypoint (angle + 90, clockwise on screen) is the same patch.
TEST(Cdikp, PatchFollowsKeypointAngle) {
  cv::Mat img = LoadSample("baboon.jpg");  // 320 x 320: pyramid levels rotate exactly too
  cv::Mat rot;
  cv::rotate(img, rot, cv::ROTATE_90_CLOCKWISE);  // (x, y) -> (H - 1 - y, x)
  for (float size : {4.f, 20.f}) {                // level 0 (spacing < 1) and level 2
    for (float angle : {0.f, 17.f, 200.f}) {
      const cv::KeyPoint kp(cv::Point2f(150.f, 120.f), size, angle);
      const cv::KeyPoint kr(cv::Point2f(float(img.rows - 1) - kp.pt.y, kp.pt.x), size, angle + 90.f);
      const cv::Mat p0 = CdikpPatch(img, kp), p1 = CdikpPatch(rot, kr);
      // The opposite rotation direction gives a different patch.
      const cv::KeyPoint kw(kr.pt, size, angle - 90.f + 360.f);
      const cv::Mat pw = CdikpPatch(rot, kw);
      const double right = cv::norm(p0, p1, cv::NORM_L2) / cv::norm(p0, cv::mean(p0)[0] * cv::Mat::ones(p0.size(), CV_32F));
      const double wrong = cv::norm(p0, pw, cv::NORM_L2) / cv::norm(p0, cv::mean(p0)[0] * cv::Mat::ones(p0.size(), CV_32F));
      if (size < 10.f) {
        // Level 0 (spacing < 1): both sample the same pixels exactly.
        EXPECT_LT(cv::norm(p0, p1, cv::NORM_INF), 0.05) << "size " << size << " angle " << angle;
      }
      // Coarser levels: pyrDown grids of the two images differ in phase, so
      // the patches differ by aliasing only.
      EXPECT_LT(right, 0.15) << "size " << size << " angle " << angle;
      EXPECT_GT(wrong, 0.5) << "size " << size << " angle " << angle;
    }
  }
}

TEST(Cdikp, DimsOptionRespected) {
  const cv::Mat img = LoadSample("fruits.jpg");
  for (int dims : {16, 32}) {
    CdikpOptions o;
    o.dims = dims;
    const cv::Ptr<CDIKP> f = CDIKP::create(o);
    EXPECT_EQ(f->descriptorSize(), dims);
    std::vector<cv::KeyPoint> kps;
    cv::Mat d;
    f->detectAndCompute(img, cv::noArray(), kps, d);
    ASSERT_FALSE(kps.empty());
    EXPECT_EQ(d.rows, int(kps.size()));
    EXPECT_EQ(d.cols, dims);
    EXPECT_EQ(d.type(), CV_32F);
    for (int i = 0; i < d.rows; ++i) EXPECT_NEAR(cv::norm(d.row(i)), 1.0, 1e-4);  // L2-normalised
  }
}

TEST(Cdikp, GrayAndBgrGiveTheSameResult) {
  const cv::Mat bgr = LoadSample("coffee.jpg", cv::IMREAD_COLOR);
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  const cv::Ptr<CDIKP> f = CDIKP::create();
  std::vector<cv::KeyPoint> k1, k2;
  cv::Mat d1, d2;
  f->detectAndCompute(bgr, cv::noArray(), k1, d1);
  f->detectAndCompute(gray, cv::noArray(), k2, d2);
  ASSERT_EQ(k1.size(), k2.size());
  EXPECT_EQ(cv::norm(d1, d2, cv::NORM_INF), 0.0);
}

TEST(Cdikp, BadInput) {
  const cv::Ptr<CDIKP> f = CDIKP::create();
  std::vector<cv::KeyPoint> kps;
  cv::Mat d;
  try {
    f->detectAndCompute(cv::Mat(), cv::noArray(), kps, d);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kBadImage);
    EXPECT_NE(std::string(e.what()).find("empty image"), std::string::npos) << e.what();
  }
  EXPECT_THROW(f->detect(cv::Mat(), kps), Error);
  EXPECT_THROW(f->compute(cv::Mat(), kps, d), Error);
  EXPECT_THROW(f->detect(cv::Mat(10, 10, CV_32F, cv::Scalar(0)), kps), Error);
  // Bad keypoints given to compute.
  std::vector<cv::KeyPoint> bad{cv::KeyPoint(5.f, 5.f, 0.f)};
  EXPECT_THROW(f->compute(cv::Mat(20, 20, CV_8U, cv::Scalar(3)), bad, d), Error);
  // Bad options.
  for (auto set : {+[](CdikpOptions& o) { o.patch_size = 24; }, +[](CdikpOptions& o) { o.scale_factor = 0; },
                   +[](CdikpOptions& o) { o.dims = 0; }, +[](CdikpOptions& o) { o.n_octave_layers = 0; }}) {
    CdikpOptions o;
    set(o);
    EXPECT_THROW(CDIKP::create(o), Error);
  }
}

TEST(Cdikp, UniformImageHasNoKeypoints) {
  const cv::Ptr<CDIKP> f = CDIKP::create();
  for (const cv::Mat& img : {cv::Mat(200, 300, CV_8UC1, cv::Scalar(128)), cv::Mat(200, 300, CV_8UC3, cv::Scalar(0, 50, 200))}) {
    std::vector<cv::KeyPoint> kps{cv::KeyPoint(1.f, 1.f, 3.f)};  // stale content is replaced
    cv::Mat d(3, 3, CV_32F, cv::Scalar(1));
    f->detectAndCompute(img, cv::noArray(), kps, d);
    EXPECT_TRUE(kps.empty());
    EXPECT_TRUE(d.empty());
  }
}

TEST(Cdikp, ComputeKeepsProvidedKeypoints) {
  const cv::Mat img = LoadSample("astronaut.jpg");
  const cv::Ptr<CDIKP> f = CDIKP::create();
  std::vector<cv::KeyPoint> kps;
  f->detect(img, kps);
  ASSERT_GT(kps.size(), 20u);
  // Add keypoints at and beyond the border, a huge one and one without orientation.
  kps.emplace_back(0.f, 0.f, 10.f, 45.f);
  kps.emplace_back(float(img.cols - 1), float(img.rows - 1), 3.f, 300.f);
  kps.emplace_back(-20.f, float(img.rows + 5), 8.f, 10.f);
  kps.emplace_back(180.f, 180.f, 400.f, 0.f);
  kps.emplace_back(100.f, 100.f, 12.f, -1.f);
  const std::vector<cv::KeyPoint> before = kps;
  cv::Mat d;
  f->compute(img, kps, d);
  ASSERT_EQ(kps.size(), before.size());
  for (std::size_t i = 0; i < kps.size(); ++i) {
    EXPECT_EQ(kps[i].pt, before[i].pt);
    EXPECT_EQ(kps[i].size, before[i].size);
    EXPECT_EQ(kps[i].angle, before[i].angle);
  }
  EXPECT_EQ(d.rows, int(kps.size()));
  EXPECT_EQ(d.cols, 20);
  for (int i = 0; i < d.rows; ++i) EXPECT_TRUE(cv::checkRange(d.row(i))) << i;
  // detectAndCompute with useProvidedKeypoints gives the same descriptors.
  cv::Mat d2;
  f->detectAndCompute(img, cv::noArray(), kps, d2, true);
  EXPECT_EQ(cv::norm(d, d2, cv::NORM_INF), 0.0);
  // No keypoints: empty descriptors.
  std::vector<cv::KeyPoint> none;
  f->compute(img, none, d);
  EXPECT_TRUE(d.empty());
}

TEST(Cdikp, MaskRestrictsDetection) {
  const cv::Mat img = LoadSample("starry_night.jpg");
  cv::Mat mask(img.size(), CV_8U, cv::Scalar(0));
  mask(cv::Rect(0, 0, img.cols / 2, img.rows)).setTo(255);
  std::vector<cv::KeyPoint> kps;
  cv::Mat d;
  CDIKP::create()->detectAndCompute(img, mask, kps, d);
  ASSERT_FALSE(kps.empty());
  for (const auto& kp : kps) EXPECT_LT(kp.pt.x, img.cols / 2 + 1);
}

}  // namespace
}  // namespace mvkp
