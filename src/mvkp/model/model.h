// A trained MVKP target and its file format.
//
// File layout (little-endian):
//   "MVKPMODL"                  8-byte magic
//   u32 format_version          kModelFormatVersion; newer files are refused,
//                               version 1 (one level, affine views) still loads
//   u64 payload_bytes
//   payload                     see model.cc (parameters, locations, descriptors)
//   u32 crc32(payload)          IEEE CRC-32
// Loading checks each of these and every count inside the payload, so a
// truncated, corrupted or future-version file gives mvkp::Error(kBadModel)
// naming the file and the problem, never a crash.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mvkp {

constexpr std::uint32_t kModelFormatVersion = 2;

// What query-side feature extraction must reproduce, and how the model was trained.
struct ModelParams {
  // Feature pipeline (must match at query time).
  float smooth_sigma = 1.0f;
  int patch_size = 32;
  int dims = 20;
  bool orient = true;
  int orientation_radius = 15;
  float min_strength = 2e-4f;
  float relative_threshold = 0.005f;
  float min_distance = 3.f;
  int block_size = 3;
  // Training record (informational).
  int views = 0;
  int locations = 0;
  int clusters = 0;
  std::uint64_t seed = 0;
  float min_scale = 0.f, max_scale = 0.f;
  double train_ms = 0;
  // Envelope (format version 2; a version-1 model reads as one affine level).
  std::uint8_t view_model = 0;   // 0: affine views (thesis), 1: camera-model views, 2: both (TrainOptions::ViewModel)
  int levels = 1;                // training pyramid levels
  float max_tilt_deg = 0.f;      // steepest training view
  float level_min_scale = 0.f, level_max_scale = 0.f;  // camera views: scale range per level
};

struct ObjectLocation {
  float x = 0.f, y = 0.f;  // object-image pixels
  int stability = 0;       // number of training views in which it was detected
  int level = 0;           // training pyramid level (0: the largest)
  float scale = 1.f;       // object-image pixels per pixel of its level
};

struct Model {
  ModelParams params;
  int object_width = 0, object_height = 0;  // size of the trained object image
  std::vector<ObjectLocation> locations;
  cv::Mat descriptors;               // M x dims, CV_32F: the k-means centres
  std::vector<std::int32_t> labels;  // M entries: index into locations

  // Throws Error(kBadModel) if sizes or labels are inconsistent.
  void Validate(const std::string& name) const;
};

std::vector<std::uint8_t> SerializeModel(const Model& model);
// `name` is used in error messages (e.g. the file path).
Model DeserializeModel(const std::uint8_t* data, std::size_t size, const std::string& name);

// Writes atomically (to a temporary file, then rename), so an interrupted save
// never leaves a half-written model in place of a good one.
void SaveModel(const Model& model, const std::string& path);
Model LoadModel(const std::string& path);

}  // namespace mvkp
