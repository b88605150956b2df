// MVKP over a nadir aerial photo, tile by tile (issue 22, thesis §7.3.1).
//
// One MVKP model of a whole nadir photo fails on oblique views that show a
// small part of it several times finer: few of the model's locations fall in
// the view, and the rest crowd the ratio test. Measured (tuning seed 1, dense
// city 0, views of 0.16-0.2 m against a 0.55 m photo): the whole photo, with
// 200 or 3000 locations, finds none of them at any scale; a 320 px tile of
// the same photo finds them with 30-40 inliers at scales 0.5 and 0.3.
//
// So the photo is cut into overlapping square tiles, each trained as an MVKP
// target. A view is searched for every tile at each scale; the verified
// matches of every tile found (homography inliers: one plane of the tile's
// part of the scene each) are pooled. The camera then comes from their 3-D
// points (view_pose.h), where the planes' parallax is what PnP explains.
#pragma once

#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/match/matcher.h"
#include "mvkp/train/trainer.h"

namespace mvkp {

struct NadirTilesOptions {
  // The photo is resized by this factor before it is cut (< 1: a photo much
  // finer than the views need trains fewer tiles); matches are returned in
  // the photo's own pixels.
  double photo_scale = 1.0;
  int tile_px = 320;      // tile side, pixels of the resized photo
  double stride = 0.75;   // tile step, share of tile_px (< 1: tiles overlap)
  TrainOptions train = DefaultTrain();
  MatchOptions match = DefaultMatch();
  void Check() const;     // throws Error(kInvalidArgument)

  // 50 training views per tile (not 100): half the training time, and the
  // same inliers on the measured views.
  static TrainOptions DefaultTrain() {
    TrainOptions t;
    t.views = 50;
    return t;
  }
  // No upsampling or simulated tilts: a tile not found at one scale is
  // usually found at another, at a fraction of the cost.
  static MatchOptions DefaultMatch() {
    MatchOptions m;
    m.upsample_points = 0;
    m.tilt_directions = 0;
    return m;
  }
};

// A verified match: nadir photo pixels <-> view pixels.
struct NadirMatch {
  cv::Point2f nadir, view;
  float distance = 0;  // descriptor distance
  int tile = -1;
};

class NadirTiles {
 public:
  // Trains every tile of `nadir_gray` (8-bit). Tiles without texture are
  // skipped; throws Error(kNoTexture) if none is left.
  NadirTiles(const cv::Mat& nadir_gray, const NadirTilesOptions& options = {});

  // Every found tile's verified matches in `view_gray` searched at `scale`
  // (area-averaged; view pixels in the result are the view's own).
  std::vector<NadirMatch> Match(const cv::Mat& view_gray, double scale) const;

  std::size_t size() const { return tiles_.size(); }
  const cv::Rect& tile(std::size_t i) const { return tiles_[i].rect; }  // in the resized photo
  double train_ms() const { return train_ms_; }

 private:
  struct Tile {
    cv::Rect rect;
    std::unique_ptr<Matcher> matcher;
  };
  std::vector<Tile> tiles_;
  double photo_scale_ = 1;
  double train_ms_ = 0;
};

}  // namespace mvkp
