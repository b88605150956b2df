// MVKP training (thesis §3.2.1, SPEC §2): from ONE object image, synthesise
// affine views, detect points in each, map them back to object coordinates,
// group them into view tracks, keep the most stable object locations, and
// describe each by k-means centres of its Walsh–Hadamard descriptors.
#pragma once

#include <cstdint>
#include <functional>

#include <opencv2/core.hpp>

#include "mvkp/model/model.h"

namespace mvkp {

struct TrainOptions {
  int views = 100;            // N_V synthetic affine views (thesis: 50-100)
  int locations = 200;        // object locations kept, most stable first (thesis: 100-200)
  int clusters = 20;          // k-means centres per location (thesis: 10-20)
  int kernels = 20;           // Walsh–Hadamard kernels = descriptor dims (thesis: 20)
  int patch = 32;             // patch side in pixels (thesis: 32)
  std::uint64_t seed = 42;    // drives view sampling, view noise and k-means
  double min_scale = 0.4;     // lambda range of the views (thesis: [0.4, 1.6])
  double max_scale = 1.6;
  int points_per_view = 600;  // strongest detections kept per view
  float track_radius = 2.0f;  // a detection joins a location within this many view pixels
  float view_noise = 2.0f;    // Gaussian noise sigma added to each view (grey levels)
  float view_blur = 1.0f;     // each view is blurred with a sigma drawn from [0, view_blur] (beyond the thesis: measured gain on blurred and held-out views)
  bool orient = true;         // orientation-normalised patches (SPEC §3); false = thesis-literal
  float smooth_sigma = 1.0f;  // Gaussian smoothing before detection
  int max_object_side = 640;  // larger targets are trained at this size (0: never downscale)
  int min_locations = 12;     // fewer stable locations than this: too little texture to train
  int kmeans_iterations = 10;
  // Called after each view with (views done, views total); may be empty.
  std::function<void(int, int)> progress;
  void Check() const;         // throws mvkp::Error(kInvalidArgument)
};

// Trains a model from an 8-bit grayscale object image. Throws
// Error(kNoTexture) when the image has too few stable interest points.
Model Train(const cv::Mat& object_gray, const TrainOptions& options = {});

}  // namespace mvkp
