// Databases and query sets for mvkp_bench_knn: random vectors, or descriptors
// extracted from real images (mvkp's own WH pipeline, or OpenCV SIFT).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "mvkp/index/fvecs.h"

namespace mvkp::bench {

struct Dataset {
  std::string source;  // one line: where the vectors come from
  VectorSet db;
  VectorSet queries;
  double generate_ms = 0;
};

// n database and nq query vectors, independent, uniform in [0, 1)^dim.
Dataset RandomDataset(std::size_t n, int dim, std::size_t nq, std::uint32_t seed);

enum class Descriptor { kWh, kSift };

// Extracts descriptors from `images` and, when that is not enough, from
// rotated and scaled copies of them (round r warps every image by the r-th
// angle/scale of a fixed sequence), until the database pool holds n and the
// query pool nq descriptors. Every 10th source image (image x round) feeds the
// query pool, the others the database pool, so no query is a database vector;
// n and nq are then drawn at random (seeded) from the pools, database vectors
// kept in extraction order.
// kWh: mvkp::ExtractFeatures with default FeatureOptions (20-D); dim is ignored.
// kSift: cv::SIFT, 128-D; dim 64 projects both sets with a cv::PCA fitted on
// the database.
Dataset ImageDataset(Descriptor kind, const std::vector<std::string>& images, std::size_t n, std::size_t nq, int dim,
                     std::uint32_t seed);

}  // namespace mvkp::bench
