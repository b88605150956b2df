// Shape-context descriptors of closed region contours (thesis §7.2.3).
//
// A contour is resampled to N_CPL points uniformly spaced along its arc
// length, ordered counter-clockwise (positive shoelace area in the contour's
// own x/y coordinates; with image y pointing down this is clockwise on screen
// — what matters is that both sides use the same convention, which a
// reflection-free transform preserves) and starting at the point with the
// smallest y. Each point j gets a log-polar histogram of the positions of all
// other points k != j:
//   angle  = direction(p_k - p_j) - tangent(p_j)   (rotation invariance: the
//            tangent at j is the x axis of the histogram frame)
//   radius = |p_k - p_j| / D                        (scale invariance: D is the
//            diagonal of the contour's minimum-area bounding rectangle)
// Histograms are normalised and stored as square roots, so that the Hellinger
// affinity of two histograms is a dot product and all N x N point affinities of
// a region pair are one matrix product.
//
// Matching two descriptors tries the N cyclic shifts (point j of one <-> point
// (j + shift) % N of the other: once one point is matched, all are); the cost
// of a shift is the mean Hellinger distance 1 - <sqrt h_a, sqrt h_b> in [0, 1].
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

using Contour = std::vector<cv::Point2f>;

struct ShapeContextOptions {
  int points = 64;            // N_CPL: resampled contour points per region
  int radial_bins = 5;        // log-spaced between r_inner and r_outer
  int angular_bins = 12;      // in the tangent frame, over 360 degrees
  double r_inner = 1.0 / 16;  // radii as a fraction of the bounding-box diagonal;
  double r_outer = 1.0;       //   below r_inner -> first bin, above r_outer -> last
  int tangent_span = 2;       // tangent at j from points j - span and j + span
  void Check() const;         // throws Error(kInvalidArgument)
};

struct ShapeDescriptor {
  Contour points;      // the N resampled points (contour coordinates)
  cv::Mat hist;        // N x (radial_bins * angular_bins) CV_32F, rows = sqrt(normalised histogram)
  cv::Mat hist_t;      // hist transposed (bins x N), for fast matching
  double scale = 0;    // D: bounding-box diagonal used for normalisation
  double area = 0;     // |area| of the resampled polygon
  int region = -1;     // index of the source contour (set by the caller)
  bool partial = false;  // built from a contiguous part of the contour (closed by a chord)
  bool empty() const { return points.empty(); }
};

// Uniform arc-length resampling of a closed contour to n points, oriented and
// started as described above. Returns an empty contour for fewer than 3
// input points or a degenerate (zero-length) contour.
Contour ResampleContour(const Contour& contour, int n);

// Signed shoelace area (positive = the orientation ResampleContour produces).
double SignedArea(const Contour& contour);

// Descriptor of one closed contour; empty() for a degenerate contour.
ShapeDescriptor DescribeContour(const Contour& contour, const ShapeContextOptions& opt = {});

// The general form (what DescribeContour computes with anchors = samples =
// the resampled contour, unit weights, its own tangents and the box
// diagonal): at each anchor j a log-polar histogram of `samples` (those
// not at the anchor itself) weighted by `weights`, angles measured from
// `tangents[j]` (radians), radii divided by `scale`. The edge-group track
// of feature fusion (thesis §7.3.2) describes virtual anchor points of an
// ordered edgelet list this way, its edgelets' midpoints weighted by their
// lengths. area is left 0.
ShapeDescriptor DescribeAnchors(const Contour& anchors, const std::vector<double>& tangents, const Contour& samples,
                                const std::vector<float>& weights, double scale, const ShapeContextOptions& opt = {});

// Partial-contour descriptors (§7.2.3, for segmentation leaks/breaks): when
// the contour's polygon approximation has at least min_corners corners, the
// contiguous runs of ceil(m/2)+1 of its m corners (each closed by the chord
// between its ends) are described as closed contours; at most max_partials of
// them (start corners spread evenly). Empty when the contour has fewer corners.
std::vector<ShapeDescriptor> DescribePartials(const Contour& contour, const ShapeContextOptions& opt = {},
                                              int min_corners = 6, int max_partials = 4);

// Number of corners of the contour's polygon approximation
// (cv::approxPolyDP, epsilon = max(1.5 px, 2 % of the perimeter)).
int CountCorners(const Contour& contour);

struct ShiftCost {
  double cost = 1;  // mean Hellinger distance at this shift, [0, 1]
  int shift = 0;    // point j of a <-> point (j + shift) % N of b
};

// Costs of all N cyclic shifts (index = shift). a and b must have the same N
// and bin layout.
std::vector<double> ShiftCosts(const ShapeDescriptor& a, const ShapeDescriptor& b);

// The best cyclic shift.
ShiftCost MatchDescriptors(const ShapeDescriptor& a, const ShapeDescriptor& b);

// Up to k shifts that are local minima of the cyclic cost curve with cost <=
// best * (1 + slack), best first (symmetric shapes — a rectangle matches at
// two shifts 180 degrees apart, a square at four).
std::vector<ShiftCost> BestShifts(const std::vector<double>& costs, int k, double slack = 0.25);

}  // namespace mvkp
