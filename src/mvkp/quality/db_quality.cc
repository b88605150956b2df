#include "mvkp/quality/db_quality.h"

#include <algorithm>
#include <map>
#include <random>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/model/model.h"
#include "mvkp/synth/camera_view.h"

namespace mvkp {
namespace {

// A stored image as 8-bit grey: in full within max_pixels (what `mvkp quality`
// decodes from the same file), else (JPEG) at 1/2, 1/4 or 1/8.
cv::Mat DecodeStoredGray(const std::string& name, const std::vector<std::uint8_t>& bytes, std::int64_t max_pixels) {
  Require(!bytes.empty(), ErrorCode::kBadImage, name + ": no stored image");
  const ImageHeader h = ReadImageHeader(name, bytes.data(), bytes.size());
  Require(h.complete, ErrorCode::kBadImage, name + ": " + h.incomplete);
  const std::int64_t px = std::int64_t(h.width) * h.height;
  int reduce = 1;
  if (h.format == "jpeg")
    while (reduce < 8 && px / (std::int64_t(reduce) * reduce) > max_pixels) reduce *= 2;
  if (reduce == 1) {
    ImageLimits lim;
    lim.max_pixels = max_pixels;
    return DecodeImageGray(name, bytes, lim);
  }
  Require(px / (std::int64_t(reduce) * reduce) <= max_pixels, ErrorCode::kBadImage,
          name + " is " + std::to_string(h.width) + "x" + std::to_string(h.height) + ", above the pixel limit (" +
              std::to_string(max_pixels) + ")");
  const int flags = reduce == 8 ? cv::IMREAD_REDUCED_GRAYSCALE_8
                    : reduce == 4 ? cv::IMREAD_REDUCED_GRAYSCALE_4
                                  : cv::IMREAD_REDUCED_GRAYSCALE_2;
  cv::Mat img = cv::imdecode(bytes, flags);
  Require(!img.empty(), ErrorCode::kBadImage, name + ": cannot be decoded");
  return img;
}

// Longest side of the probe frames: a phone frame as the recogniser sees it.
constexpr int kProbeSide = 640;

cv::Mat Shrink(const cv::Mat& gray, int side) {
  const double s = double(side) / std::max(gray.cols, gray.rows);
  if (s >= 1) return gray;
  cv::Mat out;
  cv::resize(gray, out, cv::Size(std::max(1, int(gray.cols * s)), std::max(1, int(gray.rows * s))), 0, 0,
             cv::INTER_AREA);
  return out;
}

// The stored image (at most kProbeSide) and `n` camera views of it on a busy
// backdrop, at sizes and tilts a visitor's phone sees (reproducible from seed).
std::vector<cv::Mat> ProbeFrames(const cv::Mat& gray, int n, std::uint64_t seed) {
  std::vector<cv::Mat> frames{Shrink(gray, kProbeSide)};
  CameraSceneOptions so;
  so.supersample = 2;
  const cv::Size frame(so.width, so.height);
  std::mt19937_64 rng(seed);
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  for (int i = 0; i < n; ++i) {
    CameraPose pose;
    pose.size_px = std::exp(U(std::log(220.0), std::log(420.0)));
    pose.tilt_deg = U(0, 45);
    pose.azimuth_deg = U(0, 360);
    pose.roll_deg = U(-20, 20);
    const std::uint64_t s = seed * 1000003ull + std::uint64_t(i);
    const cv::Mat bg = MakeClutterBackground(frame, s ^ 0xB6u);
    frames.push_back(MakeCameraScene(frames[0], bg, pose, so, s).image);
  }
  return frames;
}

}  // namespace

void DatabaseQualityOptions::Check() const {
  quality.Check();
  recognizer.Check();
  Require(synthetic_views >= 0 && synthetic_views <= 16, ErrorCode::kInvalidArgument,
          "synthetic views must be in 0..16");
  Require(max_pixels >= 1024, ErrorCode::kInvalidArgument, "max pixels must be >= 1024");
}

DatabaseQualityReport AssessDatabase(const std::string& db, const DatabaseQualityOptions& o) {
  o.Check();
  Timer timer;
  const TargetStore store = TargetStore::Open(db);
  DatabaseQualityReport rep;
  rep.db = o.name.empty() ? db : o.name;
  for (const TargetInfo& info : store.List()) {
    ExhibitQuality e;
    e.info = info;
    rep.exhibits.push_back(std::move(e));
  }
  const int n = int(rep.exhibits.size());

  // Every exhibit's model in one recogniser; each is taken out while probed.
  Recognizer rec(o.recognizer);
  std::map<std::string, Model> models;
  for (auto& e : rep.exhibits) {
    try {
      const TargetRecord r = store.Get(e.info.id, /*with_image=*/false);
      Model m = DeserializeModel(r.model.data(), r.model.size(), rep.db + ": target '" + e.info.id + "'");
      rec.Add(e.info.id, m);
      models.emplace(e.info.id, std::move(m));
    } catch (const Error& ex) {
      if (ex.code() == ErrorCode::kIo) throw;
      e.error = ex.what();
    }
  }

  for (int i = 0; i < n; ++i) {
    ExhibitQuality& e = rep.exhibits[std::size_t(i)];
    const std::string& id = e.info.id;
    cv::Mat gray;
    try {
      gray = DecodeStoredGray(rep.db + ": the stored image of '" + id + "'", store.Get(id, true).image, o.max_pixels);
    } catch (const Error& ex) {
      if (ex.code() == ErrorCode::kIo) throw;
      if (e.error.empty()) e.error = ex.what();
    }
    if (!gray.empty() && o.score) {
      Timer qt;
      e.quality = o.assess ? o.assess(e.info, gray) : AssessTarget(gray, o.quality);
      e.assessed = true;
      e.quality_ms = o.assess ? qt.ElapsedMs() : e.quality.ms;
    }
    if (!gray.empty() && rec.size() > (models.count(id) ? 1u : 0u)) {
      Timer pt;
      const auto mine = models.find(id);
      if (mine != models.end()) rec.Remove(id);
      const std::vector<cv::Mat> frames = ProbeFrames(gray, o.synthetic_views, o.seed + std::uint64_t(i));
      std::map<std::string, LookalikePair> seen;
      for (const cv::Mat& f : frames)
        for (const Recognition& r : rec.Recognize(f).found) {
          LookalikePair& p = seen[r.id];
          p.a = id;
          p.b = r.id;
          ++p.found_in;
          p.inliers = std::max(p.inliers, r.inliers);
        }
      for (auto& [b, p] : seen) {
        p.probes = int(frames.size());
        rep.pairs.push_back(p);
      }
      if (mine != models.end()) rec.Add(id, mine->second);
      e.probe_ms = pt.ElapsedMs();
    }
    if (o.progress) o.progress(i + 1, n);
  }
  std::stable_sort(rep.pairs.begin(), rep.pairs.end(),
                   [](const LookalikePair& x, const LookalikePair& y) { return x.inliers > y.inliers; });
  rep.ms = timer.ElapsedMs();
  return rep;
}

}  // namespace mvkp
