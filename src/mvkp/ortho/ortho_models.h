// The two small learned models of the aerial-photo segmentation (thesis
// §7.2.2, §7.2.4), each fitted once per dataset and stored as a small JSON file
// (cv::FileStorage):
//
//  * FbmModel — fractional Brownian motion model of NATURAL (non-building)
//    texture: E|I(p) - I(q)| = k |p - q|^H, fitted by least squares on
//    ln E|dI| = ln k + H ln d over labelled non-building pixels. The overall
//    fractal error (OFE) of a pixel is the RMS over distance classes d (axis
//    and diagonal offsets, d up to window/2) of  E_w|I(q) - I(q + o_d)| - k d^H,
//    the expectation E_w taken over the window x window neighbourhood (thesis:
//    F_error = E[|I(p_c) - I(p_r)|] - k |p_c - p_r|^H). A LOW OFE means "fits
//    the natural-texture model", i.e. probably not a building; smooth (roofs,
//    asphalt) and edge-crossing windows have a high OFE.
//  * RegionLda — linear discriminant on the 5-D augmented space
//    (x, y, xy, x², y²) of a contour's peak-neighbourhood ratios
//    x = PNR(H_x), y = PNR(H_y): a quadratic boundary in the PNR plane.
//    Score > 0: regular enough to be (part of) a building.
//
// Intensity everywhere is 8-bit luma (cv::COLOR_BGR2GRAY) on 0..255.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

struct FbmModel {
  double k = 0;      // E|dI| at distance 1 (grey levels); <= 0: no model
  double H = 0.5;    // Hurst exponent, 0 < H < 1 (fractal dimension D = 3 - H)
  double ofe = 0;    // mean overall fractal error on the training pixels (the "natural" OFE level)
  int window = 7;    // OFE window side (odd), thesis: 7x7
  bool Valid() const { return k > 0 && H > 0 && H < 1 && ofe > 0 && window >= 3 && window % 2 == 1; }
};

// Least-squares fBm fit on the pixels where mask != 0 (non-building areas) of
// each image (8-bit BGR or grey; masks CV_8U of the same size). Pairs whose
// both ends are masked, at all offsets inside the window, every `stride`-th
// pixel. Throws Error(kInvalidArgument) on mismatched inputs or when fewer
// than 500 masked pixels are usable. `ofe` (optional): the images'
// OverallFractalError maps under the fitted model, which the fit computes
// for the natural OFE level anyway (a caller that needs them saves a
// second pass over every pixel).
FbmModel FitFbm(const std::vector<cv::Mat>& images, const std::vector<cv::Mat>& masks,
                int window = 7, int stride = 2, std::vector<cv::Mat1f>* ofe = nullptr);

// Overall fractal error of every pixel of an 8-bit grey image (CV_32F), for
// the whole image at once with box filters (about 4 ms per megapixel and
// distance class); the image border is handled by reflection.
// Computed in row strips of `strip_rows` (0: the whole image at once); the
// result does not depend on it.
cv::Mat1f OverallFractalError(const cv::Mat1b& gray, const FbmModel& model, int strip_rows = 96);

struct RegionLda {
  std::array<double, 5> w{};  // weights on (x, y, xy, x², y²)
  double b = 0;               // bias (includes ln N1/N0)
  bool Valid() const;         // some weight non-zero, all finite
  double Score(cv::Vec2d pnr) const;  // > 0: building class
};

// The built-in model, trained by TrainRegionLda on procedurally generated
// building outlines (rectangles, L/T/U shapes, rotated, with jitter) versus
// irregular blobs and leaks (see ortho_models.cc, DefaultRegionLdaTrainingSet).
RegionLda DefaultRegionLda();

// Peak-neighbourhood ratios (PNR(H_x), PNR(H_y)) of a closed contour: its
// points (densified to 1 px steps) are rotated into the contour's own
// principal frame (peak of the length-weighted edge-direction histogram modulo 90°) and
// projected into two `bins`-bin histograms. Per histogram: PNR of the highest
// peak = mean of its existing neighbour bins / peak, PNR of the second peak
// (highest bin not next to the first) = its value / highest; the histogram's
// PNR is the mean of the two. Returns (1, 1) for fewer than 3 points.
cv::Vec2d ContourPnr(const std::vector<cv::Point>& contour, int bins = 10);

// Two-class LDA with pooled covariance in the augmented 5-D space, prior
// ln(N1/N0) in the bias. labels: 1 building, 0 not. Throws
// Error(kInvalidArgument) unless both classes have >= 3 samples.
RegionLda TrainRegionLda(const std::vector<cv::Vec2d>& pnr, const std::vector<int>& labels);

// Synthetic training set behind DefaultRegionLda (deterministic for a seed).
void DefaultRegionLdaTrainingSet(std::vector<cv::Vec2d>* pnr, std::vector<int>* labels,
                                 unsigned seed = 7);

// JSON files via cv::FileStorage. Load throws Error(kIo) for a missing file,
// Error(kBadModel) for a file without the expected fields or with invalid values.
void SaveFbmModel(const std::string& path, const FbmModel& m);
FbmModel LoadFbmModel(const std::string& path);
void SaveRegionLda(const std::string& path, const RegionLda& m);
RegionLda LoadRegionLda(const std::string& path);

}  // namespace mvkp
