// Aerial photo <-> LiDAR depth registration by region shape (thesis §7.2.3,
// §7.2.4), on plain closed contours: building regions extracted from the
// photo (ROI_a) and from the depth image (ROI_r), in pixels of each image.
//
// Algorithm (see register.cc for details):
//  1. Describe every region by shape context (shape_context.h); depth regions
//     with many corners also get partial-contour descriptors.
//  2. For every depth descriptor, scan all photo descriptors with the best
//     cyclic shift; keep the best few photo regions; cost ratio = best /
//     second-best cost over distinct photo regions.
//  3. Hypotheses, lowest cost ratio first: one region pair + one of its best
//     shifts gives N point correspondences -> a similarity (least squares).
//     Implausible ones (scale outside [min_scale, max_scale], poor fit of the
//     pair itself, rotation away from the principal-direction prediction) are
//     skipped.
//  4. Propagation = verification: all photo regions are projected into the
//     depth image; one is consistent with a depth region when most of its
//     contour lies within inlier_px of that region's contour and areas agree.
//     The transform is re-fitted on the consistent set (closest-point
//     correspondences) and propagated again until the set stops growing.
//  5. The few largest distinct consistent sets that reach min_regions and
//     min_inlier_ratio of the regions the transform maps into the other
//     image's extent are kept (the search stops early on a strong one).
//  6. Each, largest first: least squares (ICP on exact closest contour
//     points) of the similarity, affine and perspective models, propagating
//     again with the most accurate one while the set grows; kAuto keeps the
//     perspective model when it fits no worse than the similarity (from
//     perspective_min_pairs region pairs), else the similarity unless the
//     affine model clearly beats it (>= 4 pairs). Accepted when the
//     RMS is <= max_rms_px (scaled); else the next set, then the search
//     continues; when all fail: ok == false, "no registration found: ...".
// Deterministic: the only randomness (sampling hypotheses beyond the
// top-ranked ones) uses `seed`.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "mvkp/shapes/edge_evidence.h"
#include "mvkp/shapes/shape_context.h"

namespace mvkp {

struct RegionMatch {
  int a = -1, b = -1;     // photo region index, depth region index
  double cost = 1;        // shape-context matching cost at the best shift, [0, 1]
  double cost_ratio = 1;  // best / second-best cost (lower = more distinctive)
  int shift = 0;          // resampled photo point j <-> resampled depth point (j + shift) % N
};

struct RegistrationOptions {
  ShapeContextOptions shape;          // descriptor parameters (N_CPL = shape.points)
  bool partial_descriptors = true;    // partial-contour descriptors for depth regions ...
  int partial_min_corners = 6;        // ... with at least this many polygon corners
  int max_partials_per_region = 4;
  double partial_rank_penalty = 1.0;  // added to the cost ratio of partial-descriptor hypotheses
  double min_region_area = 16;        // px^2; smaller contours are ignored (both sides)
  int candidates_per_region = 3;      // photo matches kept per depth descriptor
  int shifts_per_pair = 4;            // local-minimum shifts tried per region pair
  int max_hypotheses = 600;           // seed pairs verified at most
  double min_scale = 0.2, max_scale = 5.0;  // plausible photo -> depth scale
  double inlier_px = 6;               // propagation: contour distance in depth px, times
                                      //   max(1, photo->depth scale) (photo noise grows with it)
  double inlier_fraction = 0.7;       // of a projected photo contour's points near one depth contour
  double max_area_ratio = 2.0;        // projected photo area vs depth area, either way
  double grow_tolerance = 1.5;        // final propagation: regions within this x inlier_px join the
                                      //   set (a fit of a few nearby regions is least accurate far away)
  int min_regions = 4;                // consistent region pairs needed to accept
  int min_regions_with_evidence = 3;  // ... when the image check (EdgeEvidence) passes too
  double min_inlier_ratio = 0.3;      // consistent / regions mapped into the overlap
  double min_inlier_ratio_with_evidence = 0.2;  // ... when the image check passes too
  double max_rms_px = 2.5;            // final RMS contour distance needed to accept (scaled as
                                      //   inlier_px, and by clamp((pairs - 1) / 5, 0.5, 1): few pairs, tighter)
  double edge_rms_factor = 2.0;       // with image evidence (EdgeEvidence): max RMS = this * the
                                      //   shape-only bound, since the outlines-on-edges test decides
  double relocate_rms_free_gain = 0.15;  // a relocation (EdgeEvidence::Relocate) must leave the region pairs
                                      //   within the RMS bound above, unless it puts the outlines on edges
                                      //   this much better (EdgeScore::on) at no lower edge contrast: pairs
                                      //   of roof regions the photo segmentation drew with their cast
                                      //   shadows hold the answer off the edges (issue 21); 0: always bound
  bool edge_refine = true;            // with image evidence: snap the outlines onto the photo edges
  bool joint_lean_fit = true;         // ... and also refine the lean from the region pairs refitted
                                      //   with it (an affine + the lean by least squares)
  double joint_lean_gain = 0.15;      // ... which replaces the first lean answer when its edge
                                      //   contrast is this share higher
  double lean_min_roof_ratio = 0.95;  // the lean answer replaces the lean-free one only when the
                                      //   roofs inside its outlines (EdgeEvidence::ScoreRoofs) stand
                                      //   apart at least this share as much: of 20 replacements that
                                      //   lowered them by > 5 %, 14 moved the answer off the truth and 1
                                      //   onto it (issue 21); 0: the edges alone decide
  double max_perspective = 0.25;       // refuse a transform whose projective divisor changes by more
                                      //   than this across the photo's regions (a nadir photo's changes
                                      //   by a few per cent; wrong sets fitted 0.3+); 0: no check
  double max_anisotropy = 1.15;       // refuse a transform that stretches the photo more along one
                                      //   axis than the other, at the centre of its regions, by more
                                      //   than this ratio (square pixels seen from above: 1; a camera
                                      //   30 deg off nadir: 1.155; non-square GeoTIFF pixels need
                                      //   more); 0: no check
  bool require_image_evidence = true; // with image evidence given: accept only through it (shapes
                                      //   alone gave answers 120-850 px off on towns of small
                                      //   look-alike houses); false: shapes alone may also accept
  // The single-pair route (issue 21), with image evidence only: when no
  // consistent set of region pairs passes, each region pair's own
  // similarity is scored by the image check, z = (contrast - 1) *
  // sqrt(outline samples in view); the best distinct pose is accepted as a
  // layout: >= single_pair_min_outlines depth outlines in view,
  // single_pair_min_on_edges of them on edges, and a margin over the best
  // clearly different pose, whatever its outlines in view (confidence =
  // (z1 - z2) / z1 >= single_pair_min_confidence). One pair is the
  // weakest evidence, so its roofs must stand apart however clear the
  // edges: a roof contrast below EdgeEvidenceOptions::roof_veto (over
  // min_roof_veto_regions outlines or more) refuses it even at an edge
  // contrast above roof_veto_below (a photo of other ground: edges 3.18,
  // roofs 0.54 over 6 outlines; the route's right answers score roofs
  // 1.74-3.98).
  bool single_pair_route = true;
  double single_pair_min_seed_contrast = 1.2;  // a pair's raw transform must score this to be refined
  int single_pair_poses = 8;                   // distinct poses refined and compared
  double single_pair_distinct_px = 20;         // poses this far apart (depth px, photo corners) differ
  int single_pair_min_outlines = 8;
  double single_pair_min_on_edges = 0.5;
  double single_pair_min_confidence = 0.5;
  // Determined, not just plausible (issue 21): an answer's perspective is
  // perturbed 8 ways (the projective divisor tilted by +-ambiguity_perspective
  // across the photo, about its centre) and each is refined sharply on the
  // edges again (with the lean, when the answer has one). If a pose reached so
  // scores at least the answer's contrast and lies more than ambiguity_px
  // away on average over the outlines in view (EdgeEvidence::MeanGap), the
  // evidence does not tell them apart: no answer. (Near misses 5-12 px off
  // were right by the matched regions and off far from them; measured in
  // docs/aerial.md.) With image evidence and a perspective model only;
  // 0 turns it off.
  double ambiguity_px = 5;
  double ambiguity_perspective = 0.12;
  bool use_principal_directions = false; // §7.2.4: try hypotheses whose rotation fits the
                                         //   principal directions first; falls back to all
  double principal_tolerance_deg = 12;   // allowed rotation deviation from a predicted one
  enum class Model { kSimilarity, kAffine, kPerspective, kAuto } model = Model::kAuto;
  int perspective_min_pairs = 4;      // kAuto: region pairs needed before the perspective model is
                                      //   considered (ICP on all their contour points: well posed)
  std::uint64_t seed = 1;
  void Check() const;  // throws Error(kInvalidArgument)
};

struct Registration {
  bool ok = false;
  std::string reason;                 // "no registration found: ..." when !ok, else a summary
  cv::Matx33d photo_to_depth = cv::Matx33d::eye();  // when ok
  std::string model;                  // "similarity" | "affine" | "perspective"
  std::vector<std::pair<cv::Point2f, cv::Point2f>> correspondences;  // photo px -> depth px
  std::vector<RegionMatch> region_matches;  // accepted region pairs (propagated ones with their matching cost)
  double rms_px = 0;                  // RMS contour distance of the correspondences, depth px
  int hypotheses = 0;                 // seed hypotheses verified
  bool used_principal_directions = false;  // the restricted search produced the result
  double match_ms = 0, propagate_ms = 0;   // description + matching; hypotheses + refinement
  EdgeScore edge;                     // image evidence of the result (of the last candidate when !ok)
  std::string route = "regions";      // "regions" (a consistent set of region pairs) | "single-pair"
  double route_confidence = 0;        // single-pair route: its margin confidence (see the options)
  double ambiguity_px = 0;            // the largest mean gap to an equally good pose found (see
                                      //   RegistrationOptions::ambiguity_px); of the last candidate when !ok
  cv::Point2d lean_px_per_m{0, 0};    // the photo's lean (edge_evidence.h), depth px per metre of
                                      //   height: roofs show this far from their footprints; the
                                      //   transform maps the ground. Zero unless estimated.
  double relocated_px = 0;            // how far EdgeEvidence::Relocate moved the answer (mean over
                                      //   the outlines in view, depth px); 0 when it kept it
  std::vector<cv::Matx33d> refused;   // the fitted poses of the consistent sets that failed the checks,
                                      //   in the order tried (best first): hints for a later pass, never answers
};

// `evidence` (optional, not owned): the photo and all depth outlines (see
// edge_evidence.h): `depth_regions` themselves, in the same order, since
// their heights there give the lean (joint_lean_fit). With it, a candidate needs outlines on photo edges
// (EdgeEvidence::Accepts) but may fit the region shapes more loosely
// (edge_rms_factor), and the result is snapped onto the edges (edge_refine).
Registration RegisterContours(const std::vector<Contour>& photo_regions,
                              const std::vector<Contour>& depth_regions,
                              const RegistrationOptions& options = {},
                              const EdgeEvidence* evidence = nullptr);

// The nadir-photo shape checks of a photo -> depth transform over
// `photo_extent` (photo px): max_perspective and max_anisotropy of
// `options`. "" when it passes, else why. Every route applies them
// (RegisterContours; the outline search in aerial.h).
std::string NadirShape(const cv::Matx33d& photo_to_depth, const cv::Rect2d& photo_extent,
                       const RegistrationOptions& options);

// The largest mean gap (depth px, over the outlines in view) between the
// answer `photo_to_depth` (with its `lean`) and a pose refined sharply from
// one of 8 perspective perturbations of it (+-ambiguity_perspective across
// `photo_extent`) that scores at least the answer's edge contrast: how far
// off an equally good pose lies (RegistrationOptions::ambiguity_px).
double AmbiguityGap(const EdgeEvidence& evidence, const cv::Matx33d& photo_to_depth, cv::Point2d lean,
                    const RegistrationOptions& options, const cv::Rect2d& photo_extent);

// Applies a 3x3 transform to points (perspective division).
Contour TransformPoints(const cv::Matx33d& T, const Contour& points);

// Principal directions (§7.2.4): Canny -> probabilistic Hough -> 36-bin
// histogram of segment directions (length-weighted, over [0, 180) degrees);
// the highest peak, refined by interpolating the 3 bins around it, is the
// first direction (degrees, [0, 180)); the second is the highest peak at
// least 45 degrees away. nullopt when too few segments or no distinct peak.
struct PrincipalDirections {
  double first_deg = 0, second_deg = 0;
};
std::optional<PrincipalDirections> DetectPrincipalDirections(const cv::Mat& image);
// The same on region contours (drawn into an edge image, Canny skipped).
std::optional<PrincipalDirections> DetectPrincipalDirections(const std::vector<Contour>& regions);

}  // namespace mvkp
