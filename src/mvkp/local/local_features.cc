#include "mvkp/local/local_features.h"

#include <cmath>
#include <limits>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {
namespace {

class Pipeline final : public LocalFeatureMethod {
 public:
  Pipeline(const std::string& name, cv::Ptr<cv::Feature2D> f, int norm, bool augment, const LocalFeatureOptions& o)
      : LocalFeatureMethod(name), f_(std::move(f)), norm_(norm), augment_(augment), opt_(o) {}

  int descriptor_bytes() const override {
    if (augment_) return f_->descriptorSize() * (f_->descriptorSize() <= 255 ? 1 : 2);
    return f_->descriptorSize() * int(CV_ELEM_SIZE(f_->descriptorType()));
  }

  LocalFeatures Extract(const cv::Mat& gray) const override {
    Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
            name() + ": needs a non-empty 8-bit grayscale image");
    LocalFeatures r;
    Timer t;
    f_->detect(gray, r.keypoints);
    r.detect_ms = t.ElapsedMs();
    t.Restart();
    if (!r.keypoints.empty()) f_->compute(gray, r.keypoints, r.descriptors);
    r.describe_ms = t.ElapsedMs();
    if (r.descriptors.empty()) r.keypoints.clear();
    if (augment_ && !r.keypoints.empty()) {
      t.Restart();
      r.codes = Augment(r.keypoints, r.descriptors, opt_.augment);
      r.augment_ms = t.ElapsedMs();
    }
    return r;
  }

  std::vector<NearestTwo> Match(const LocalFeatures& object, const LocalFeatures& query) const override {
    std::vector<NearestTwo> out;
    if (object.keypoints.empty() || query.keypoints.empty()) return out;
    const float inf = std::numeric_limits<float>::infinity();
    if (augment_) {
      Require(!object.codes.empty() && !query.codes.empty() && object.codes.type() == query.codes.type() &&
                  object.codes.cols == query.codes.cols,
              ErrorCode::kInvalidArgument, name() + ": both feature sets need ordinal codes of the same size");
      const auto two = KnnMatchCodes(query.codes, object.codes, opt_.metric);
      out.reserve(two.size());
      for (int q = 0; q < int(two.size()); ++q)
        out.push_back({q, two[q].best, two[q].second, float(two[q].d1), two[q].second < 0 ? inf : float(two[q].d2)});
      return out;
    }
    Require(object.descriptors.type() == query.descriptors.type() && object.descriptors.cols == query.descriptors.cols,
            ErrorCode::kInvalidArgument, name() + ": mismatched descriptor types");
    std::vector<std::vector<cv::DMatch>> knn;
    cv::BFMatcher(norm_).knnMatch(query.descriptors, object.descriptors, knn, 2);
    out.reserve(knn.size());
    for (const auto& m : knn) {
      if (m.empty()) continue;
      NearestTwo n{m[0].queryIdx, m[0].trainIdx, -1, m[0].distance, inf};
      if (m.size() > 1) {
        n.second = m[1].trainIdx;
        n.d2 = m[1].distance;
      }
      out.push_back(n);
    }
    return out;
  }

 private:
  cv::Ptr<cv::Feature2D> f_;
  int norm_;
  bool augment_;
  LocalFeatureOptions opt_;
};

}  // namespace

void LocalFeatureOptions::Check() const {
  Require(max_features >= 0, ErrorCode::kInvalidArgument, "max features must be >= 0");
  cdikp.Check();
  augment.Check();
}

const std::vector<std::string>& LocalFeatureMethodNames() {
  static const std::vector<std::string> names = {"cdikp", "sift", "orb", "akaze", "aug-sift", "aug-cdikp"};
  return names;
}

std::unique_ptr<LocalFeatureMethod> LocalFeatureMethod::Create(const std::string& name, const LocalFeatureOptions& o) {
  o.Check();
  auto cdikp = [&] {
    CdikpOptions c = o.cdikp;
    if (o.max_features > 0) c.nfeatures = o.max_features;
    return CDIKP::create(c);
  };
  auto sift = [&] { return cv::SIFT::create(o.max_features); };
  if (name == "cdikp") return std::make_unique<Pipeline>(name, cdikp(), cv::NORM_L2, false, o);
  if (name == "sift") return std::make_unique<Pipeline>(name, sift(), cv::NORM_L2, false, o);
  if (name == "aug-cdikp") return std::make_unique<Pipeline>(name, cdikp(), cv::NORM_L2, true, o);
  if (name == "aug-sift") return std::make_unique<Pipeline>(name, sift(), cv::NORM_L2, true, o);
  if (name == "orb")
    return std::make_unique<Pipeline>(name, cv::ORB::create(o.max_features > 0 ? o.max_features : 5000), cv::NORM_HAMMING,
                                      false, o);
  if (name == "akaze") return std::make_unique<Pipeline>(name, cv::AKAZE::create(), cv::NORM_HAMMING, false, o);
  std::string list;
  for (const auto& n : LocalFeatureMethodNames()) list += (list.empty() ? "" : ", ") + n;
  throw Error(ErrorCode::kInvalidArgument, "unknown method '" + name + "' (mvkp, " + list + ")");
}

}  // namespace mvkp
