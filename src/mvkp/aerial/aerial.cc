#include "mvkp/aerial/aerial.h"

#include <algorithm>
#include <optional>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"

namespace mvkp {

void AerialOptions::Check() const {
  Require(photo_max_side >= 0, ErrorCode::kInvalidArgument, "AerialOptions.photo_max_side must be >= 0");
  depth.Check();
  optical.Check();
  edge.Check();
  registration.Check();
}

AerialRegistration RegisterAerial(cv::Mat1f depth, cv::Mat photo, const AerialOptions& o) {
  o.Check();
  Require(!depth.empty(), ErrorCode::kBadImage, "aerial registration: empty depth image");
  Require(!photo.empty() && photo.depth() == CV_8U && (photo.channels() == 1 || photo.channels() == 3),
          ErrorCode::kBadImage, "aerial registration: the photo must be a non-empty 8-bit grey or BGR image");
  AerialRegistration out;
  // The order keeps peak memory low: the full-size photo goes before the depth
  // segmentation's working maps exist, the depth before the photo's.
  Timer tp;
  double f = 1.0;
  if (o.photo_max_side > 0 && std::max(photo.cols, photo.rows) > o.photo_max_side) {
    f = double(o.photo_max_side) / std::max(photo.cols, photo.rows);
    cv::Mat small;
    cv::resize(photo, small, cv::Size(), f, f, cv::INTER_AREA);
    photo = std::move(small);  // the full-size pixels go unless the caller keeps them
  }
  cv::Mat grey;
  if (o.image_check) {
    if (photo.channels() == 3) cv::cvtColor(photo, grey, cv::COLOR_BGR2GRAY);
    else grey = photo;
  }
  double photo_ms = tp.ElapsedMs();

  Timer td;
  const std::vector<BuildingRegion> dregions = SegmentDepth(depth, o.depth);
  depth.release();
  out.segment_depth_ms = td.ElapsedMs();
  for (const auto& r : dregions) out.depth_regions.emplace_back(r.contour.begin(), r.contour.end());

  tp.Restart();
  const std::vector<PhotoRegion> pregions = SegmentOptical(std::move(photo), o.optical);
  // contours back in full-size photo px (pixel centres at integers)
  for (const auto& r : pregions) {
    Contour c;
    c.reserve(r.contour.size());
    for (const auto& p : r.contour) c.emplace_back(float((p.x + 0.5) / f - 0.5), float((p.y + 0.5) / f - 0.5));
    out.photo_regions.push_back(std::move(c));
    out.photo_region_confidence.push_back(r.confidence);
  }
  out.segment_photo_ms = photo_ms + tp.ElapsedMs();

  std::optional<EdgeEvidence> evidence;
  if (!grey.empty()) evidence.emplace(grey, f, out.depth_regions, o.edge);
  grey.release();
  out.registration = RegisterContours(out.photo_regions, out.depth_regions, o.registration,
                                      evidence ? &*evidence : nullptr);
  return out;
}

}  // namespace mvkp
