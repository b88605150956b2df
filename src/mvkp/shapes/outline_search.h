// Second registration method (issue 21): a global search of the depth's
// building outlines over the photo's oriented edges, for the cases the region
// method (register.h) cannot handle: few buildings (3-6 region pairs are not
// enough evidence) and coarse photos (buildings a few photo px across, which
// the photo segmentation does not separate).
//
// No photo segmentation is used. The depth outlines (every segmented building
// region) are a template of oriented points; the photo is a field of oriented
// gradient, in the doubled-angle form  P = m * exp(2i phi)  (m the gradient
// magnitude normalised by its mean and clipped, phi its direction), so an
// outline normal psi scores  m cos 2(phi - psi): + on an edge along the
// outline whatever its polarity, - across it, 0 on average at random.
//
//  1. Rotation prior: the histograms of outline normals (depth) and photo
//     gradient directions, both modulo 90 degrees, are cross-correlated; the
//     best `rotation_peaks` offsets, each +- rotation_window_deg, x 4
//     quadrants, are the rotations searched (all 360 degrees when the
//     histograms have no clear peak: round or irregular buildings).
//  2. Coarse search: the depth is seen in cells of c depth px (c: a fifth of
//     the median building side, at least the outline extent / 48). For each
//     scale hypothesis (log steps; the range narrowed to the ratio of ground
//     resolutions when both are known) the photo is resampled to cells and
//     its field Fourier-transformed once; for each rotation the template is
//     splatted into cells and correlated with it by FFT, giving every
//     translation at once. A translation's score is a z-score: the
//     correlation over sqrt(null variance x outline samples in the photo),
//     with at least min_overlap of the samples in the photo.
//  3. The best distinct coarse poses are refined at photo resolution
//     (coordinate ascent of the same score on the similarity), then by the
//     image check's edge refinement (EdgeEvidence::Refine, similarity then
//     homography) when an EdgeEvidence is given. A refined pose's score is
//     weighted by its completeness (completeness_power): the share of the
//     building outlines' arcs in view that lie on edges.
//  4. Acceptance (never a wrong success): the best refined pose must beat
//     the best refined pose that is clearly different (its outlines > 10
//     depth px away on average: a null from the same search, which accounts
//     for how many poses were tried), and the outlines must lie on edges.
//     confidence = clamp(2 (z1 - z2) / z1, 0, 1) with z1, z2 those two
//     refined scores; accepted when confidence >= min_confidence (0.5, i.e.
//     the runner-up scores at most 3/4 of the best), at least min_outlines
//     (2) outlines are in view, and with an EdgeEvidence its contrast passes
//     (1.8) with at least half of the outlines in view on edges.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/shapes/edge_evidence.h"
#include "mvkp/shapes/shape_context.h"

namespace mvkp {

struct OutlineSearchOptions {
  double min_scale = 0.25, max_scale = 4.0;  // depth px per photo px searched (when no hint)
  double scale_hint = 0;            // > 0: expected depth px per photo px (ratio of ground resolutions) ...
  double scale_hint_tolerance = 0.15;  // ... searched within this relative margin
  double max_extent_ratio = 4.0;    // photo ground extent / outline extent, at most (bounds the scales)
  double min_extent_ratio = 0.2;    // ... at least
  double cells_per_building = 5;    // coarse cell = median building side / this ...
  int max_template_radius = 24;     // ... but the outline template at most this many cells in radius
  double step_factor = 1.0;         // rotation / log-scale step = step_factor / template radius (rad)
  int rotation_peaks = 2;           // rotation prior: offsets (mod 90 deg) kept
  double rotation_window_deg = 6;   // searched around each offset
  double min_rotation_peakiness = 1.6;  // histogram correlation max / mean below this: search 360 deg
  double min_overlap = 0.25;        // share of outline samples inside the photo for a pose
  int min_samples = 60;             // outline samples inside the photo, at least
  int coarse_candidates = 30;       // distinct coarse poses refined
  double distinct_px = 10;          // poses whose outlines differ by more than this (mean, depth px)
                                    //   are different answers
  double min_confidence = 0.5;      // accepted at confidence >= this ...
  int min_outlines = 2;             // ... with this many outlines in view (1 is not enough: a lone
                                    //   outline sits on any similar rectangle of other ground), for the
                                    //   search and, with evidence, for the image check too, which must
                                    //   pass with at least min_on_edges of the outlines in view on edges
  double min_on_edges = 0.5;
  // Objects (trees, hedges, sheds: the `objects` of SearchOutlines) join the
  // score at this weight per sample: their crowns and ends are ragged, and a
  // tree lines up with any textured patch (at 1 they cost answers; issue 21).
  double object_weight = 0.5;
  // Completeness (issue 21, small tiles): each refined pose's score is
  // multiplied by the share of its building outlines' arcs in view (8
  // samples each) whose own score is positive, to this power (0: off). The
  // score sums over samples, so a pose that lays two sides of each roof on a
  // road's edges scores as well as the roofs themselves; only the roofs put
  // the rest of their outlines on edges too.
  double completeness_power = 1.0;
  // An answer needs at least this completeness (the same share, at the
  // answer; 0: off). A pose on other ground lays some sides of several
  // outlines on a similar street grid's edges, not their whole outlines:
  // two photos of other ground that passed every other check (of 120
  // photos of other suburbs, towns and civic centres, large tiles) had
  // 0.58 and 0.67; the 72 answers of seven seed sets, right and wrong,
  // 0.84 or more (docs/aerial.md).
  double min_completeness = 0.8;
  bool perspective = true;          // final EdgeEvidence refinement includes the homography; with
                                    //   evidence, an answer must then hold under it (move its outlines
                                    //   < distinct_px): a similarity the refinement leaves is not the pose
  void Check() const;               // throws Error(kInvalidArgument)
};

struct OutlineSearchResult {
  bool ok = false;
  std::string reason;
  cv::Matx33d photo_to_depth = cv::Matx33d::eye();  // contour (full-size) photo px -> depth px
  std::string model;                 // "similarity" | "perspective"
  double confidence = 0;             // [0, 1]
  double score = 0, runner_up = 0;   // refined z-scores of the best and of the best clearly different pose
  double coverage = 0;               // share of outline samples inside the photo at the answer
  double completeness = 0;           // share of the building outlines' arcs in view on edges at the answer
  int outlines_in_view = 0;          // outlines with >= 10 samples inside the photo at the answer
  EdgeScore edge;                    // image check at the answer (when evidence given)
  cv::Point2d lean_px_per_m{0, 0};   // the photo's lean estimated by the final refinement (edge_evidence.h)
  double relocated_px = 0;           // how far EdgeEvidence::Relocate moved the answer (depth px; 0: kept)
  bool roof_vetoed = false;          // set by RegisterAerial: refused by the roof veto (roof_veto, edge_evidence.h)
  bool held = true;                  // the image check's perspective refinement left the pose < distinct_px
  int poses = 0;                     // (rotation, scale) pairs correlated
  double ambiguity_px = 0;           // set by RegisterAerial: the mean gap to an equally good pose
                                     //   (AmbiguityGap, register.h) when it judged the answer
  double ms = 0;
};

// `photo`: 8-bit grey or BGR, possibly downscaled: contour px * photo_scale =
// image px (as EdgeEvidence). `outlines`: closed building outlines, depth px.
// `evidence` (optional): the image check on the same outlines and scene (its
// photo may be larger than `photo`: both are addressed in contour px); used
// for the final refinement and acceptance.
// `objects` (optional): outlines of what else stands above the ground (trees,
// hedges, sheds: ObjectOutlines, depth_regions.h), depth px. They join the
// template the poses are scored by (at object_weight), never the outline
// count, the cell size, the completeness or the acceptance, which stay the
// buildings'.
OutlineSearchResult SearchOutlines(const cv::Mat& photo, double photo_scale, const std::vector<Contour>& outlines,
                                   const OutlineSearchOptions& options = {}, const EdgeEvidence* evidence = nullptr,
                                   const std::vector<Contour>* objects = nullptr);

}  // namespace mvkp
