// Feature fusion for wide-baseline urban images (issue 22, method 2; thesis
// §7.3.2): correspondences between the nadir photo and an oblique view from
// two tracks of high-level features that do not need texture.
//
//  * ROI track: building regions by region growing with vegetation and edge
//    maps, in-region edges and selective smoothing (ortho/optical_regions.h,
//    shared with stage 1), described by shape contexts of their contours and
//    partial contours (shapes/shape_context.h).
//  * Edge-group track: line segments of the photo (LSD) cut into short
//    straight "edgelets"; each edgelet votes, over the pixels it covers, for
//    the regions within label_radius_px (the nearest one, and others nearly
//    as near), takes the label of its vote histogram's first peak (and a
//    second when the second peak is close), and edgelets of one label form a
//    group. A group is chained into ordered edgelet lists (OEL): start at the
//    edgelet with an end nearest the group's bounding-box corner, append the
//    edgelet whose end is nearest the list's outgoing end (within link_px),
//    until none is near or the list closes. Each list is described at N_VAP
//    virtual anchor points spaced evenly along it: log-polar histograms of
//    the list's edgelet midpoints weighted by their lengths, angles in the
//    frame of the list's tangent at the anchor (rotation), radii over the
//    diagonal of the list's minimum-area rectangle (scale). Long lists also
//    get partial descriptors of contiguous runs (over-grouping).
//  * Matching, per track: each view feature against every nadir feature of
//    the track (a first layer keeps the `shortlist` nearest by mean
//    histogram, then the best cyclic shift of the anchors); the cost ratio
//    best / second best (another source feature) must be low. A matched
//    pair gives its anchors' point-to-point correspondences; both tracks'
//    correspondences are merged for the robust fit (view_pose.h).
//
// Where this differs from the thesis: edgelets come from LSD segments, not
// from Canny pixels grouped into lines (the same short straight pieces, with
// sub-pixel ends); lists are oriented like contours (positive shoelace area
// of the list closed by its chord) so that two views traverse a list the
// same way; and the robust fit is a camera (PnP), not a homography.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/oblique/nadir_tiles.h"
#include "mvkp/ortho/optical_regions.h"
#include "mvkp/shapes/shape_context.h"

namespace mvkp {

struct FusionOptions {
  // Images larger than this (longer side, px) are area-resized to it for the
  // features; positions are reported in the input's pixels. 0: never.
  int work_px = 1024;
  // --- ROI track
  OpticalSegmentOptions roi;
  ShapeContextOptions region_shape;        // 64 contour points
  int partial_corners = 6, max_partials = 4;
  // --- edge-group track
  double max_edgelet_px = 12;   // longer segments are cut into equal pieces no longer than this
  double min_edgelet_px = 4;    // shorter segments are dropped
  double label_radius_px = 12;  // an edgelet votes for the regions within this distance
  double second_label = 1.5;    // ... the nearest one, and any other within this x its distance
  double second_peak = 0.7;     // a second label when the second peak reaches this x the first
  double link_px = 6;           // an OEL grows by an edgelet whose end is this near its outgoing end
  int min_list_edgelets = 6;    // shorter lists are not described
  ShapeContextOptions group_shape{40};     // points = N_VAP (thesis: 30-50)
  int list_partials = 3;        // partial descriptors (60 % runs) of lists of >= 2 x min_list_edgelets
  // --- matching
  int shortlist = 12;           // first layer: nadir candidates per view feature
  double max_cost = 0.45;       // of the best shift (mean Hellinger distance)
  double max_cost_ratio = 0.9;  // best / second best source feature
  // Nadir features kept per view feature (each from another source). The
  // thesis keeps one; on the four views of tuning seed 1 / dense / city 0,
  // eight raised the right feature pairs from 0-2 to 1-4 per view while
  // multiplying the wrong ones by eight: left at one.
  int candidates = 1;
  int max_matches = 60;         // per track, lowest cost ratio first
  int pair_step = 2;            // every pair_step-th anchor pair of a matched feature is kept
  void Check() const;           // throws Error(kInvalidArgument)
};

struct Edgelet {
  cv::Point2f a, b;     // input px, in list order once listed
  int label = -1;       // region (first peak); -1: none near
  int label2 = -1;      // second peak, or -1
  int list = -1;        // the ordered list this copy joined (an edgelet of two groups is in two lists)
};

struct FusionFeatures {
  std::vector<ShapeDescriptor> regions;  // ROI contours and partials; .region = source region
  std::vector<ShapeDescriptor> lists;    // OEL anchors; .region = source list
  std::vector<Edgelet> edgelets;         // the listed ones, list by list in order, input px
  std::vector<std::vector<cv::Point>> roi_contours;  // input px
  int rois = 0, oels = 0;
  double ms = 0;
};

// The features of an 8-bit BGR or grey image (the vegetation map needs
// colour). Throws Error(kInvalidArgument) for an empty or non-8-bit image.
FusionFeatures ExtractFusionFeatures(const cv::Mat& image, const FusionOptions& options = {});

struct FusionMatchStats {
  int region_matches = 0, list_matches = 0;  // feature pairs kept
  // per feature pair (NadirMatch.tile): the view feature it came from
  // (regions: region index; lists: kListSource + list index), so that the
  // partial descriptors of one feature count once
  std::vector<int> view_source;
  double ms = 0;
};
constexpr int kListSource = 1 << 20;

// Point correspondences nadir <-> view from both tracks. NadirMatch.tile
// numbers the feature pair a correspondence comes from (region pairs first,
// then list pairs); distance is the pair's matching cost.
std::vector<NadirMatch> MatchFusion(const FusionFeatures& nadir, const FusionFeatures& view,
                                    const FusionOptions& options = {}, FusionMatchStats* stats = nullptr);

// Camera hypotheses from feature pairs (the thesis's outlier removal, for a
// camera). A feature pair's correspondences all come from one region or
// list, so one wrong pair is as self-consistent as a right one, and a RANSAC
// over points would pick the largest single feature. Instead each feature
// pair proposes the camera its own points give (SQPnP; it must look at them
// from above), and a camera is scored by the number of feature pairs
// (distinct view features) that agree with it: at least agree_share of
// their points reproject within agree_px. Hypotheses are returned best
// first (most agreeing features, then points), each refitted on its
// agreeing points twice; the caller verifies them (register_view.h).
struct FeatureConsensusOptions {
  double agree_px = 12;
  double agree_share = 0.5;
  int min_points = 8;   // a feature pair with fewer points proposes nothing
};
struct CameraHypothesis {
  cv::Matx33d R;                // world -> camera: x = R X + t
  cv::Vec3d t;
  int features = 0;             // view features agreeing
  int points = 0;               // their points within agree_px
  std::vector<char> agree;      // per correspondence
};
std::vector<CameraHypothesis> FeatureHypotheses(const std::vector<cv::Point3d>& world,
                                                const std::vector<cv::Point2d>& pixels,
                                                const std::vector<int>& pair_of, const std::vector<int>& view_source,
                                                const cv::Matx33d& K, int max_hypotheses,
                                                const FeatureConsensusOptions& options = {});

// The view with both tracks drawn: regions' contours (green) and the
// lists' edgelets (one colour per list).
cv::Mat DrawFusionFeatures(const cv::Mat& image, const FusionFeatures& f);

}  // namespace mvkp
