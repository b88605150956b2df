#include "mvkp/pose/pose.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;

constexpr int kObjW = 400, kObjH = 300;  // object image, pixels
constexpr double kWidthM = 0.4;          // its physical width, metres

CameraModel Synthetic() {
  CameraModel c;
  c.K = cv::Matx33d(500, 0, 319.5, 0, 500, 239.5, 0, 0, 1);
  c.image_size = {640, 480};
  return c;
}

// Object pixels -> target-plane metres (centre origin), as pose.h defines them.
cv::Matx33d PixelsToPlane() {
  const double s = kWidthM / kObjW;
  return {s, 0, -(kObjW - 1) / 2.0 * s, 0, s, -(kObjH - 1) / 2.0 * s, 0, 0, 1};
}

// The exact homography of the plane seen by an undistorted camera: K [r1 r2 t] S.
cv::Matx33d PlaneHomography(const cv::Matx33d& K, const cv::Matx33d& R, const cv::Vec3d& t) {
  const cv::Matx33d M(R(0, 0), R(0, 1), t[0], R(1, 0), R(1, 1), t[1], R(2, 0), R(2, 1), t[2]);
  return K * M * PixelsToPlane();
}

struct TruePose {
  cv::Matx33d R;
  cv::Vec3d t;
};

// Target centre 0.5-3 m away, near the middle of the view, tilted up to 50° about a random in-plane axis
// and rolled at random: the target faces the camera.
TruePose RandomPose(std::mt19937& rng, const CameraModel& cam) {
  std::uniform_real_distribution<double> u(0, 1);
  const double d = 0.5 + 2.5 * u(rng);
  const cv::Vec3d ray = cam.K.inv() * cv::Vec3d(220 + 200 * u(rng), 160 + 160 * u(rng), 1);
  const double tilt = 50.0 * CV_PI / 180 * u(rng), axis = 2 * CV_PI * u(rng), roll = 2 * CV_PI * u(rng);
  cv::Matx33d Rt, Rr;
  cv::Rodrigues(cv::Vec3d(std::cos(axis), std::sin(axis), 0) * tilt, Rt);
  cv::Rodrigues(cv::Vec3d(0, 0, roll), Rr);
  return {Rt * Rr, ray * (d / cv::norm(ray))};
}

double AngleDeg(const cv::Matx33d& A, const cv::Matx33d& B) {
  cv::Vec3d r;
  cv::Rodrigues(A.t() * B, r);
  return cv::norm(r) * 180 / CV_PI;
}

std::vector<cv::Point3d> PlaneGrid(int n, std::vector<cv::Point2d>* pixels) {
  const cv::Matx33d S = PixelsToPlane();
  std::vector<cv::Point3d> out;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double u = (kObjW - 1) * double(i) / (n - 1), v = (kObjH - 1) * double(j) / (n - 1);
      const cv::Vec3d p = S * cv::Vec3d(u, v, 1);
      out.emplace_back(p[0], p[1], 0);
      pixels->emplace_back(u, v);
    }
  return out;
}

// The homography a matcher would see in a distorted frame: fitted (least squares) to the distorted
// projections of an n x n grid; exact when n = 2.
cv::Matx33d DistortedHomography(const CameraModel& cam, const TruePose& p, int n) {
  std::vector<cv::Point2d> pixels, frame;
  const std::vector<cv::Point3d> grid = PlaneGrid(n, &pixels);
  cv::Vec3d rvec;
  cv::Rodrigues(p.R, rvec);
  cv::projectPoints(grid, rvec, p.t, cv::Mat(cam.K), cam.dist, frame);
  const cv::Mat H = cv::findHomography(pixels, frame, 0);
  return cv::Matx33d(H.ptr<double>());
}

TEST(Pose, RecoversRandomPosesFromExactHomographies) {
  const CameraModel cam = Synthetic();
  std::mt19937 rng(20240611);
  for (int k = 0; k < 200; ++k) {
    const TruePose truth = RandomPose(rng, cam);
    const Pose p = EstimatePose(PlaneHomography(cam.K, truth.R, truth.t), kObjW, kObjH, kWidthM, cam);
    ASSERT_TRUE(p.ok) << "pose " << k;
    EXPECT_LT(cv::norm(p.tvec - truth.t), 0.01 * cv::norm(truth.t)) << "pose " << k;
    EXPECT_LT(AngleDeg(p.R, truth.R), 0.5) << "pose " << k;
    EXPECT_NEAR(p.distance, cv::norm(truth.t), 0.01 * cv::norm(truth.t));
    EXPECT_LT(p.reprojection_px, 0.01);
    cv::Matx33d R;
    cv::Rodrigues(p.rvec, R);
    EXPECT_LT(cv::norm(R - p.R), 1e-9);
  }
}

TEST(Pose, HomographyScaleAndSignDoNotMatter) {
  const CameraModel cam = Synthetic();
  std::mt19937 rng(3);
  const TruePose truth = RandomPose(rng, cam);
  const cv::Matx33d H = PlaneHomography(cam.K, truth.R, truth.t);
  const Pose a = EstimatePose(H, kObjW, kObjH, kWidthM, cam), b = EstimatePose(H * -3.7, kObjW, kObjH, kWidthM, cam);
  ASSERT_TRUE(a.ok && b.ok);
  EXPECT_LT(cv::norm(a.tvec - b.tvec), 1e-6);
}

TEST(Pose, TranslationScalesWithPhysicalWidth) {
  const CameraModel cam = Synthetic();
  std::mt19937 rng(5);
  const TruePose truth = RandomPose(rng, cam);
  const cv::Matx33d H = PlaneHomography(cam.K, truth.R, truth.t);
  const Pose p = EstimatePose(H, kObjW, kObjH, 2 * kWidthM, cam);
  ASSERT_TRUE(p.ok);
  EXPECT_LT(cv::norm(p.tvec - 2 * truth.t), 0.01 * cv::norm(truth.t));
  EXPECT_LT(AngleDeg(p.R, truth.R), 0.5);
}

TEST(Pose, DistortionIsAccountedFor) {
  CameraModel cam = Synthetic();
  cam.dist = (cv::Mat_<double>(1, 5) << -0.25, 0.1, 0.001, -0.0005, -0.02);
  CameraModel ignored = cam;
  ignored.dist = cv::Mat();
  std::mt19937 rng(11);
  PoseOptions corners;
  corners.grid = 2;
  corners.max_reprojection_px = 1e3;
  double worst_without = 0;
  for (int k = 0; k < 100; ++k) {
    const TruePose truth = RandomPose(rng, cam);
    // Corners only: H through the four distorted corners is exact, so the pose must be too.
    const cv::Matx33d H4 = DistortedHomography(cam, truth, 2);
    const Pose p = EstimatePose(H4, kObjW, kObjH, kWidthM, cam, corners);
    ASSERT_TRUE(p.ok) << "pose " << k;
    EXPECT_LT(cv::norm(p.tvec - truth.t), 0.01 * cv::norm(truth.t)) << "pose " << k;
    EXPECT_LT(AngleDeg(p.R, truth.R), 0.5) << "pose " << k;
    const Pose q = EstimatePose(H4, kObjW, kObjH, kWidthM, ignored, corners);
    if (q.ok) worst_without = std::max(worst_without, cv::norm(q.tvec - truth.t) / cv::norm(truth.t));
    // A homography fitted over the whole distorted target (what RANSAC gives), default 3x3 grid: close.
    const Pose r = EstimatePose(DistortedHomography(cam, truth, 21), kObjW, kObjH, kWidthM, cam);
    ASSERT_TRUE(r.ok) << "pose " << k;
    EXPECT_LT(cv::norm(r.tvec - truth.t), 0.03 * cv::norm(truth.t)) << "pose " << k;
    EXPECT_LT(AngleDeg(r.R, truth.R), 3.0) << "pose " << k;
  }
  EXPECT_GT(worst_without, 0.02);  // the distortion used here matters
}

TEST(Pose, SameAnswerOnAResizedFrame) {
  const CameraModel cam = Synthetic();
  std::mt19937 rng(17);
  const TruePose truth = RandomPose(rng, cam);
  const cv::Matx33d H = PlaneHomography(cam.K, truth.R, truth.t);
  // cv::resize by 1/2: x' = (x + 0.5) / 2 - 0.5.
  const cv::Matx33d half(0.5, 0, -0.25, 0, 0.5, -0.25, 0, 0, 1);
  const Pose p = EstimatePose(half * H, kObjW, kObjH, kWidthM, ScaledTo(cam, {320, 240}));
  ASSERT_TRUE(p.ok);
  EXPECT_LT(cv::norm(p.tvec - truth.t), 1e-6 * cv::norm(truth.t));
  EXPECT_LT(AngleDeg(p.R, truth.R), 1e-4);
}

TEST(Pose, RejectsImplausibleHomographies) {
  const CameraModel cam = Synthetic();
  std::mt19937 rng(23);
  const TruePose truth = RandomPose(rng, cam);
  const cv::Matx33d H = PlaneHomography(cam.K, truth.R, truth.t);
  // Mirrored: the target would be seen from behind.
  const cv::Matx33d flip(-1, 0, kObjW - 1, 0, 1, 0, 0, 0, 1);
  EXPECT_FALSE(EstimatePose(H * flip, kObjW, kObjH, kWidthM, cam).ok);
  // Degenerate and non-finite.
  EXPECT_FALSE(EstimatePose(cv::Matx33d::zeros(), kObjW, kObjH, kWidthM, cam).ok);
  EXPECT_FALSE(EstimatePose(cv::Matx33d(1, 0, 0, 1, 0, 0, 0, 0, 1), kObjW, kObjH, kWidthM, cam).ok);
  cv::Matx33d nan = H;
  nan(1, 1) = std::nan("");
  EXPECT_FALSE(EstimatePose(nan, kObjW, kObjH, kWidthM, cam).ok);
  // The horizon crosses the target: part of it would be behind the camera.
  const cv::Matx33d horizon(1, 0, 0, 0, 1, 0, -1.0 / 200, 0, 1);
  EXPECT_FALSE(EstimatePose(horizon, kObjW, kObjH, kWidthM, cam).ok);
  // Strong perspective that this camera cannot produce: a close, tilted view through a lens 5x wider can
  // only be fitted with a large error.
  TruePose near{truth.R, cv::Vec3d(0, 0, 0.3)};
  cv::Rodrigues(cv::Vec3d(60 * CV_PI / 180, 0, 0), near.R);
  CameraModel wide = cam;
  wide.K(0, 0) = wide.K(1, 1) = 100;
  const Pose wrong = EstimatePose(PlaneHomography(wide.K, near.R, near.t), kObjW, kObjH, kWidthM, cam);
  EXPECT_FALSE(wrong.ok);
  PoseOptions loose;
  loose.max_reprojection_px = 1e4;
  const Pose fitted = EstimatePose(PlaneHomography(wide.K, near.R, near.t), kObjW, kObjH, kWidthM, cam, loose);
  ASSERT_TRUE(fitted.ok);
  EXPECT_GT(fitted.reprojection_px, 10);
}

TEST(Pose, BadArgumentsThrow) {
  const CameraModel cam = Synthetic();
  const cv::Matx33d H = cv::Matx33d::eye();
  EXPECT_THROW(EstimatePose(H, 0, kObjH, kWidthM, cam), Error);
  EXPECT_THROW(EstimatePose(H, kObjW, -1, kWidthM, cam), Error);
  EXPECT_THROW(EstimatePose(H, kObjW, kObjH, 0, cam), Error);
  EXPECT_THROW(EstimatePose(H, kObjW, kObjH, std::nan(""), cam), Error);
  PoseOptions o;
  o.grid = 1;
  EXPECT_THROW(EstimatePose(H, kObjW, kObjH, kWidthM, cam, o), Error);
}

class CameraFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           ("mvkp_pose_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::string Text(const std::string& name, const std::string& text) const {
    std::ofstream(Path(name)) << text;
    return Path(name);
  }
  // The message of the Error that LoadCamera(path) throws, checked to be of `code` and to name the file.
  static std::string LoadError(const std::string& path, ErrorCode code) {
    try {
      LoadCamera(path);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), code) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      return e.what();
    }
    ADD_FAILURE() << path << ": no error";
    return "";
  }
  fs::path dir_;
};

TEST_F(CameraFile, RoundTripOfTheOpenCvSampleKeys) {
  const cv::Matx33d K(812.5, 0, 640.2, 0, 810.1, 359.7, 0, 0, 1);
  const cv::Mat dist = (cv::Mat_<double>(5, 1) << -0.1, 0.05, 0.001, 0.002, -0.01);
  for (const std::string name : {"calib.yml", "calib.xml", "calib.json"}) {
    {
      cv::FileStorage fs(Path(name), cv::FileStorage::WRITE);
      fs << "image_width" << 1280 << "image_height" << 720 << "camera_matrix" << cv::Mat(K)
         << "distortion_coefficients" << dist << "avg_reprojection_error" << 0.31;
    }
    const CameraModel c = LoadCamera(Path(name));
    EXPECT_LT(cv::norm(c.K - K), 1e-12) << name;
    EXPECT_EQ(c.image_size, cv::Size(1280, 720)) << name;
    ASSERT_EQ(c.dist.total(), 5u) << name;
    EXPECT_EQ(c.dist.rows, 1);
    EXPECT_EQ(c.dist.type(), CV_64F);
    EXPECT_LT(cv::norm(c.dist.reshape(1, 5), dist), 1e-12) << name;
  }
}

TEST_F(CameraFile, AliasesFloatMatricesAndOptionalKeys) {
  {
    cv::FileStorage fs(Path("a.yml"), cv::FileStorage::WRITE);
    fs << "cameraMatrix" << cv::Mat(cv::Matx33f(500, 0, 320, 0, 500, 240, 0, 0, 1))
       << "distCoeffs" << cv::Mat(cv::Matx14f(0.1f, 0, 0, 0));
  }
  const CameraModel c = LoadCamera(Path("a.yml"));
  EXPECT_EQ(c.K(0, 0), 500);
  EXPECT_EQ(c.K(1, 2), 240);
  EXPECT_EQ(c.dist.total(), 4u);
  EXPECT_EQ(c.image_size, cv::Size());
  {
    cv::FileStorage fs(Path("b.yml"), cv::FileStorage::WRITE);
    fs << "camera_matrix" << cv::Mat(cv::Matx33d(500, 0, 320, 0, 500, 240, 0, 0, 1));
  }
  EXPECT_TRUE(LoadCamera(Path("b.yml")).dist.empty());
}

TEST_F(CameraFile, BadFilesGiveOneLineErrorsNamingTheFile) {
  LoadError(Path("missing.yml"), ErrorCode::kIo);
  LoadError(dir_.string(), ErrorCode::kIo);  // a directory
  LoadError(Text("text.yml", "hello: [1, 2\n  oops: {"), ErrorCode::kInvalidArgument);
  LoadError(Text("garbage.yml", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16)), ErrorCode::kInvalidArgument);
  LoadError(Text("empty.yml", ""), ErrorCode::kInvalidArgument);
  const std::string head = "%YAML:1.0\n---\n";
  const std::string k = "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                        "  data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n";
  EXPECT_NE(LoadError(Text("nok.yml", head + "image_width: 640\n"), ErrorCode::kInvalidArgument).find("camera_matrix"),
            std::string::npos);
  LoadError(Text("scalar.yml", head + "camera_matrix: 3\n"), ErrorCode::kInvalidArgument);
  LoadError(Text("2x3.yml", head + "camera_matrix: !!opencv-matrix\n  rows: 2\n  cols: 3\n  dt: d\n"
                                   "  data: [ 500., 0., 320., 0., 500., 240. ]\n"),
            ErrorCode::kInvalidArgument);
  EXPECT_NE(LoadError(Text("negf.yml", head + "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                                              "  data: [ -500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n"),
                      ErrorCode::kInvalidArgument)
                .find("focal"),
            std::string::npos);
  LoadError(Text("lastrow.yml", head + "camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
                                       "  data: [ 500., 0., 320., 0., 500., 240., 0., 1., 1. ]\n"),
            ErrorCode::kInvalidArgument);
  LoadError(Text("dist3.yml", head + k + "distortion_coefficients: [ 0.1, 0.2, 0.3 ]\n"), ErrorCode::kInvalidArgument);
  LoadError(Text("distmat.yml", head + k + "distortion_coefficients: !!opencv-matrix\n  rows: 2\n  cols: 2\n"
                                           "  dt: d\n  data: [ 0., 0., 0., 0. ]\n"),
            ErrorCode::kInvalidArgument);
  LoadError(Text("wonly.yml", head + k + "image_width: 640\n"), ErrorCode::kInvalidArgument);
  LoadError(Text("wneg.yml", head + k + "image_width: 640\nimage_height: -480\n"), ErrorCode::kInvalidArgument);
  // A plain list of 5 numbers is a valid distortion vector.
  EXPECT_EQ(LoadCamera(Text("list.yml", head + k + "distortion_coefficients: [ 0.1, 0.2, 0, 0, 0.3 ]\n")).dist.total(),
            5u);
}

TEST(ScaledTo, ScalesPerAxisAndRefusesAnotherAspect) {
  CameraModel c = Synthetic();
  const CameraModel same = ScaledTo(c, {640, 480});
  EXPECT_EQ(same.K, c.K);
  const CameraModel big = ScaledTo(c, {1280, 960});
  EXPECT_DOUBLE_EQ(big.K(0, 0), 1000);
  EXPECT_DOUBLE_EQ(big.K(1, 1), 1000);
  EXPECT_DOUBLE_EQ(big.K(0, 2), 639.5);  // still the centre of the larger frame
  EXPECT_DOUBLE_EQ(big.K(1, 2), 479.5);
  EXPECT_EQ(big.image_size, cv::Size(1280, 960));
  // 1920x1080 -> 854x480 is a resize with rounding, not a crop.
  c.image_size = {1920, 1080};
  EXPECT_NO_THROW(ScaledTo(c, {854, 480}));
  try {
    ScaledTo(c, {640, 480});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("1920x1080"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ScaledTo(c, {0, 480}), Error);
  // Unknown calibration size: used as is.
  c.image_size = {};
  EXPECT_EQ(ScaledTo(c, {100, 100}).K, c.K);
}

}  // namespace
}  // namespace mvkp
