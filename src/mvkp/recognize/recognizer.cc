#include "mvkp/recognize/recognizer.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/index/ffva.h"

namespace mvkp {

void RecognizerOptions::Check() const {
  match.Check();
  Require(max_candidates >= 1 && max_candidates <= 100000, ErrorCode::kInvalidArgument,
          "max candidates must be in 1..100000");
  Require(min_votes >= 4, ErrorCode::kInvalidArgument, "min votes must be >= 4");
  Require(min_inliers >= 4, ErrorCode::kInvalidArgument, "min inliers must be >= 4");
}

namespace {

// Name of the first query-side feature setting that differs, or "".
std::string FeatureMismatch(const ModelParams& a, const ModelParams& b) {
  if (a.smooth_sigma != b.smooth_sigma) return "smooth_sigma";
  if (a.patch_size != b.patch_size) return "patch_size";
  if (a.dims != b.dims) return "dims";
  if (a.orient != b.orient) return "orient";
  if (a.orientation_radius != b.orientation_radius) return "orientation_radius";
  if (a.min_strength != b.min_strength) return "min_strength";
  if (a.relative_threshold != b.relative_threshold) return "relative_threshold";
  if (a.min_distance != b.min_distance) return "min_distance";
  if (a.block_size != b.block_size) return "block_size";
  return "";
}

struct Vote {
  cv::Point2f object, query;
};

// Robust fit over one target's correspondences (as Matcher::Verify).
bool VerifyTarget(const std::vector<Vote>& votes, const Model& model, const RecognizerOptions& o, Recognition& out) {
  std::vector<cv::Point2f> src, dst;
  src.reserve(votes.size());
  dst.reserve(votes.size());
  for (const auto& v : votes) {
    src.push_back(v.object);
    dst.push_back(v.query);
  }
  cv::theRNG().state = 0x12345678;  // reproducible RANSAC
  const GeometryFit g = FitGeometry(src, dst, o.match);
  if (!g.ok || g.inliers < o.min_inliers) return false;
  const cv::Matx33d Hm = g.homography;
  const int inl = g.inliers;
  const std::array<cv::Point2f, 4> quad = ProjectOutline(Hm, model.object_width, model.object_height);
  if (!IsPlausibleOutline(quad)) return false;
  out.homography = Hm;
  out.outline = quad;
  out.inliers = inl;
  out.votes = int(votes.size());
  out.score = double(inl) / double(votes.size());
  return true;
}

}  // namespace

Recognizer::Recognizer(const RecognizerOptions& options) : options_(options), mutex_(std::make_unique<std::mutex>()) {
  options_.Check();
}
Recognizer::~Recognizer() = default;
Recognizer::Recognizer(Recognizer&&) noexcept = default;
Recognizer& Recognizer::operator=(Recognizer&&) noexcept = default;

void Recognizer::Add(const std::string& id, const Model& model) {
  Require(!id.empty(), ErrorCode::kInvalidArgument, "target id must not be empty");
  Require(!Contains(id), ErrorCode::kInvalidArgument, "target '" + id + "' already exists");
  model.Validate("target '" + id + "'");
  if (!targets_.empty()) {
    const std::string diff = FeatureMismatch(targets_.front().model.params, model.params);
    Require(diff.empty(), ErrorCode::kInvalidArgument,
            "target '" + id + "': feature setting " + diff + " differs from the targets already added (e.g. '" +
                targets_.front().id + "'); all targets must share the query-side feature settings");
  }
  targets_.push_back({id, model});
  dirty_ = true;
}

bool Recognizer::Remove(const std::string& id) {
  auto it = std::find_if(targets_.begin(), targets_.end(), [&](const Target& t) { return t.id == id; });
  if (it == targets_.end()) return false;
  targets_.erase(it);
  focus_.erase(id);
  dirty_ = true;
  return true;
}

bool Recognizer::Contains(const std::string& id) const {
  return std::any_of(targets_.begin(), targets_.end(), [&](const Target& t) { return t.id == id; });
}

std::vector<std::string> Recognizer::ids() const {
  std::vector<std::string> out;
  for (const auto& t : targets_) out.push_back(t.id);
  return out;
}

void Recognizer::EnsureIndex() const {
  std::lock_guard<std::mutex> lock(*mutex_);
  if (!dirty_) return;
  index_.reset();
  label_target_.clear();
  target_offset_.clear();
  if (!targets_.empty()) {
    const int dims = targets_.front().model.params.dims;
    std::size_t rows = 0;
    for (const auto& t : targets_) rows += std::size_t(t.model.descriptors.rows);
    std::vector<float> data;
    std::vector<std::int32_t> labels;
    data.reserve(rows * std::size_t(dims));
    labels.reserve(rows);
    std::int64_t offset = 0;
    for (std::size_t ti = 0; ti < targets_.size(); ++ti) {
      const Model& m = targets_[ti].model;
      Require(offset + std::int64_t(m.locations.size()) < std::numeric_limits<std::int32_t>::max(),
              ErrorCode::kInvalidArgument, "too many object locations over all targets");
      target_offset_.push_back(std::int32_t(offset));
      for (int r = 0; r < m.descriptors.rows; ++r) {
        const float* p = m.descriptors.ptr<float>(r);
        data.insert(data.end(), p, p + dims);
        labels.push_back(std::int32_t(offset + m.labels[std::size_t(r)]));
      }
      label_target_.insert(label_target_.end(), m.locations.size(), std::int32_t(ti));
      offset += std::int64_t(m.locations.size());
    }
    index_ = MakeIndexByName(options_.match.index);
    index_->Build(data.data(), rows, dims, labels.data());
  }
  dirty_ = false;
}

RecognitionResult Recognizer::RecognizeOne(const cv::Mat& gray, const std::string& id) const {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "recognise: expected a non-empty 8-bit grayscale frame");
  std::shared_ptr<const Matcher> m;
  {
    std::lock_guard<std::mutex> lock(*mutex_);
    auto it = focus_.find(id);
    if (it == focus_.end()) {
      const Target* t = nullptr;
      for (const auto& x : targets_)
        if (x.id == id) t = &x;
      Require(t != nullptr, ErrorCode::kInvalidArgument, "recognise: no target '" + id + "'");
      MatchOptions mo = options_.match;
      mo.min_inliers = options_.min_inliers;
      it = focus_.emplace(id, std::make_shared<const Matcher>(t->model, mo)).first;
    }
    m = it->second;
  }
  const MatchResult mr = m->Match(gray);
  RecognitionResult r;
  r.keypoints = mr.keypoints;
  r.matches = int(mr.matches.size());
  r.candidates = 1;
  r.detect_ms = mr.time.smooth_ms + mr.time.detect_ms;
  r.describe_ms = mr.time.describe_ms;
  r.search_ms = mr.time.search_ms;
  r.verify_ms = mr.time.verify_ms;
  if (mr.found) {
    Recognition x;
    x.id = id;
    x.homography = mr.homography;
    x.outline = mr.outline;
    x.inliers = mr.inliers;
    x.votes = int(mr.matches.size());
    x.score = x.votes ? double(x.inliers) / x.votes : 0.0;
    r.found.push_back(x);
  }
  return r;
}

RecognitionResult Recognizer::Recognize(const cv::Mat& gray) const {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "recognise: expected a non-empty 8-bit grayscale frame");
  RecognitionResult r;
  if (targets_.empty()) return r;
  EnsureIndex();

  const FeatureOptions fo = QueryFeatureOptions(targets_.front().model.params, options_.match.max_points);
  const Features f = ExtractFeatures(gray, fo);
  r.keypoints = int(f.keypoints.size());
  r.detect_ms = f.smooth_ms + f.detect_ms;
  r.describe_ms = f.describe_ms;

  // Nearest centre and nearest centre of another location (of any target),
  // ratio test on L2 distances; each kept match votes for its target.
  Timer ts;
  const std::size_t n = f.keypoints.size();
  std::vector<Neighbor> nn(2 * n);
  const float ratio = options_.match.ratio;
  if (n > 0) index_->SearchTwoDistinctBatch(f.descriptors.ptr<float>(0), n, nn.data(), ratio);
  std::vector<std::vector<Vote>> votes(targets_.size());
  for (std::size_t i = 0; i < n; ++i) {
    const Neighbor& a = nn[2 * i];
    const Neighbor& b = nn[2 * i + 1];
    if (a.id < 0) continue;
    const float d1 = std::sqrt(a.distance);
    const float d2 = b.id < 0 ? std::numeric_limits<float>::infinity() : std::sqrt(b.distance);
    if (!(d1 < ratio * d2)) continue;
    const int ti = label_target_[std::size_t(a.label)];
    const auto& loc = targets_[std::size_t(ti)].model.locations[std::size_t(a.label - target_offset_[std::size_t(ti)])];
    votes[std::size_t(ti)].push_back({{loc.x, loc.y}, {f.keypoints[i].x, f.keypoints[i].y}});
    ++r.matches;
  }
  r.search_ms = ts.ElapsedMs();

  // Candidates: enough votes to be verified and to reach min_inliers; most votes first.
  Timer tv;
  const int need = std::max(options_.min_votes, options_.min_inliers);
  std::vector<int> cand;
  for (std::size_t ti = 0; ti < targets_.size(); ++ti)
    if (int(votes[ti].size()) >= need) cand.push_back(int(ti));
  std::stable_sort(cand.begin(), cand.end(), [&](int a, int b) { return votes[std::size_t(a)].size() > votes[std::size_t(b)].size(); });
  if (int(cand.size()) > options_.max_candidates) cand.resize(std::size_t(options_.max_candidates));
  r.candidates = int(cand.size());
  for (int ti : cand) {
    Recognition rec;
    if (VerifyTarget(votes[std::size_t(ti)], targets_[std::size_t(ti)].model, options_, rec)) {
      rec.id = targets_[std::size_t(ti)].id;
      r.found.push_back(std::move(rec));
    }
  }
  std::stable_sort(r.found.begin(), r.found.end(), [](const Recognition& a, const Recognition& b) { return a.inliers > b.inliers; });
  r.verify_ms = tv.ElapsedMs();
  return r;
}

std::size_t Recognizer::memory_bytes() const {
  EnsureIndex();
  std::size_t bytes = index_ ? index_->memory_bytes() : 0;
  bytes += label_target_.size() * sizeof(std::int32_t) + target_offset_.size() * sizeof(std::int32_t);
  for (const auto& t : targets_) {
    bytes += sizeof(Target) + t.id.size() + t.model.descriptors.total() * t.model.descriptors.elemSize() +
             t.model.labels.size() * sizeof(std::int32_t) + t.model.locations.size() * sizeof(ObjectLocation);
  }
  return bytes;
}

}  // namespace mvkp
