#include "mvkp/oblique/nadir_tiles.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void NadirTilesOptions::Check() const {
  Require(tile_px >= 64 && tile_px <= 4096, ErrorCode::kInvalidArgument, "tile_px must be in [64, 4096]");
  Require(stride > 0.1 && stride <= 1.0, ErrorCode::kInvalidArgument, "stride must be in (0.1, 1]");
  Require(photo_scale >= 0.05 && photo_scale <= 1.0, ErrorCode::kInvalidArgument, "photo_scale must be in [0.05, 1]");
  match.Check();
}

namespace {

// Tile origins along one side: evenly spread so the last tile ends at the edge.
std::vector<int> Origins(int side, int tile, double stride) {
  if (side <= tile) return {0};
  const int n = int(std::ceil(double(side - tile) / (stride * tile))) + 1;
  std::vector<int> o;
  for (int i = 0; i < n; ++i) o.push_back(int(std::lround(double(i) * (side - tile) / (n - 1))));
  return o;
}

}  // namespace

NadirTiles::NadirTiles(const cv::Mat& nadir, const NadirTilesOptions& options) {
  options.Check();
  Require(!nadir.empty() && nadir.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "NadirTiles: an 8-bit grey nadir photo is required");
  Timer t;
  photo_scale_ = options.photo_scale;
  cv::Mat photo = nadir;
  if (photo_scale_ != 1.0) cv::resize(nadir, photo, cv::Size(), photo_scale_, photo_scale_, cv::INTER_AREA);
  const int tw = std::min(options.tile_px, photo.cols), th = std::min(options.tile_px, photo.rows);
  for (int y : Origins(photo.rows, th, options.stride)) {
    for (int x : Origins(photo.cols, tw, options.stride)) {
      const cv::Rect r(x, y, tw, th);
      try {
        Model m = Train(photo(r).clone(), options.train);
        tiles_.push_back({r, std::make_unique<Matcher>(m, options.match)});
      } catch (const Error& e) {
        if (e.code() != ErrorCode::kNoTexture) throw;  // a flat tile (water, a field): nothing to find
      }
    }
  }
  Require(!tiles_.empty(), ErrorCode::kNoTexture, "the nadir photo has no texture to train on");
  train_ms_ = t.ElapsedMs();
}

std::vector<NadirMatch> NadirTiles::Match(const cv::Mat& view, double scale) const {
  Require(!view.empty() && view.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "NadirTiles: an 8-bit grey view is required");
  Require(scale > 0 && scale <= 4, ErrorCode::kInvalidArgument, "NadirTiles: scale must be in (0, 4]");
  cv::Mat q = view;
  if (scale != 1.0) cv::resize(view, q, cv::Size(), scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  std::vector<NadirMatch> out;
  for (std::size_t i = 0; i < tiles_.size(); ++i) {
    const MatchResult m = tiles_[i].matcher->Match(q);
    if (!m.found) continue;
    const cv::Point2f o(float(tiles_[i].rect.x), float(tiles_[i].rect.y));
    for (const auto& c : m.matches)
      if (c.inlier)
        out.push_back({(c.object + o) * float(1.0 / photo_scale_), c.query * float(1.0 / scale), c.distance, int(i)});
  }
  return out;
}

}  // namespace mvkp
