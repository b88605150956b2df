// Minimum-eigenvalue interest point detector (thesis §3.2.1, SPEC §2.3).
//
// Points are local maxima over 3x3 of the smaller eigenvalue of the structure
// tensor (Shi–Tomasi), above a strength threshold, at least min_distance
// apart, strongest first. Strength is OpenCV's cornerMinEigenVal scale
// (gradients of an 8-bit image normalised to [0, 1] intensity units).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

struct Keypoint {
  float x = 0.f;         // column, pixels
  float y = 0.f;         // row, pixels
  float strength = 0.f;  // minimum eigenvalue
  float angle = 0.f;     // patch orientation in radians (set by the describer)
};

struct DetectorOptions {
  int max_points = 500;              // keep the N strongest (thesis: ~500 per query frame)
  float min_strength = 2e-4f;        // absolute threshold on the minimum eigenvalue
  float relative_threshold = 0.005f; // also drop points below this fraction of the frame's strongest
  float min_distance = 3.f;          // no two points closer than this (pixels)
  int border = 8;                    // ignore this many pixels at the image border
  int block_size = 3;                // structure tensor window
  // Every part of the frame gets a share: the image is cut into square cells
  // (grid_cells along its longer side) and a first pass takes, in each cell,
  // its strongest points up to an equal quota of grid_share * max_points;
  // the rest of the budget goes to the strongest remaining points anywhere.
  // A low-contrast target in a high-contrast scene then still gets points
  // (issue 18). grid_share 0: the N strongest of the frame (thesis).
  int grid_cells = 8;
  float grid_share = 0.5f;
  void Check() const;                // throws mvkp::Error(kInvalidArgument)
};

// Minimum eigenvalue of the 3x3 structure tensor of Sobel gradients, in one
// fused pass; equal to cv::cornerMinEigenVal(gray, eig, 3, 3) away from the
// outermost two rows and columns, which are set to 0. Output: CV_32F.
void MinEigen3x3(const cv::Mat& gray, cv::Mat& eig);

// Detects points on an 8-bit grayscale image (normally already smoothed).
// If mask is non-empty (8-bit, same size), only pixels where mask != 0 count.
std::vector<Keypoint> DetectMinEigen(const cv::Mat& gray, const DetectorOptions& options,
                                     const cv::Mat& mask = cv::Mat());

}  // namespace mvkp
