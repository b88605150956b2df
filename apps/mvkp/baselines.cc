#include "baselines.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/calib3d.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp::cli {

Baseline::Baseline(const std::string& name, int max_features) : name_("opencv-" + name) {
  if (name == "sift") f_ = cv::SIFT::create(max_features);
  else if (name == "orb") { f_ = cv::ORB::create(max_features); norm_ = cv::NORM_HAMMING; }
  else if (name == "akaze") { f_ = cv::AKAZE::create(); norm_ = cv::NORM_HAMMING; }
  else if (name == "brisk") { f_ = cv::BRISK::create(); norm_ = cv::NORM_HAMMING; }
  else if (name == "asift") {
    // ASIFT (Morel & Yu): SIFT on the affine views OpenCV's AffineFeature
    // simulates (tilts up to 4*sqrt(2), as in the paper). Tens of thousands
    // of features per image, so matching uses FLANN kd-trees, as OpenCV's
    // asift sample does, rather than brute force.
    f_ = cv::AffineFeature::create(cv::SIFT::create());
    flann_ = true;
  }
  else throw Error(ErrorCode::kInvalidArgument, "unknown baseline '" + name + "' (sift, orb, akaze, brisk, asift)");
}

void Baseline::Prepare(const cv::Mat& object) { f_->detectAndCompute(object, cv::noArray(), kobj_, dobj_); }

BaselineResult Baseline::Frame(const cv::Mat& frame) const {
  BaselineResult r;
  Timer t;
  std::vector<cv::KeyPoint> k;
  cv::Mat d;
  f_->detectAndCompute(frame, cv::noArray(), k, d);
  r.keypoints = int(k.size());
  std::vector<std::vector<cv::DMatch>> knn;
  if (!d.empty() && dobj_.rows >= 2) {
    if (flann_) {
      cv::FlannBasedMatcher fm(cv::makePtr<cv::flann::KDTreeIndexParams>(4), cv::makePtr<cv::flann::SearchParams>(32));
      fm.knnMatch(d, dobj_, knn, 2);
    } else {
      cv::BFMatcher(norm_).knnMatch(d, dobj_, knn, 2);
    }
  }
  for (auto& m : knn)
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      r.object_pts.push_back(kobj_[m[0].trainIdx].pt);
      r.query_pts.push_back(k[m[0].queryIdx].pt);
    }
  cv::Mat H;
  if (r.object_pts.size() >= 4)
    H = cv::findHomography(r.object_pts, r.query_pts, cv::RANSAC, 3.0, r.inlier, 2000, 0.995);
  r.ms = t.ElapsedMs();
  if (!H.empty()) {
    r.found = true;
    r.homography = cv::Matx33d(H.ptr<double>());
  }
  r.inlier.resize(r.object_pts.size(), 0);
  return r;
}

cv::Matx33d ReadHomography(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open homography file");
  cv::Matx33d H;
  for (int i = 0; i < 9; ++i)
    if (!(in >> H.val[i])) throw Error(ErrorCode::kInvalidArgument, path + ": expected 9 numbers (a 3x3 homography)");
  return H;
}

std::vector<ManifestPair> ReadManifest(const std::string& path) {
  namespace fs = std::filesystem;
  std::ifstream in(path);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open manifest");
  const fs::path base = fs::path(path).parent_path();
  std::vector<ManifestPair> out;
  std::string line;
  int no = 0;
  while (std::getline(in, line)) {
    ++no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ss(line);
    ManifestPair p;
    if (!(ss >> p.img1 >> p.img2 >> p.h))
      throw Error(ErrorCode::kInvalidArgument, path + ":" + std::to_string(no) + ": expected 'img1 img2 H'");
    auto rel = [&](std::string& s) {
      if (s != "none" && fs::path(s).is_relative()) s = (base / s).string();
    };
    rel(p.img1);
    rel(p.img2);
    rel(p.h);
    p.set = base.filename().string();
    out.push_back(p);
  }
  return out;
}

}  // namespace mvkp::cli
