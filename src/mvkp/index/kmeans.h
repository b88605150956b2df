// Small seeded k-means (k-means++ initialisation, Lloyd iterations): the
// per-location clustering of training descriptors, and the coarse quantiser
// of a matcher's inverted file.
#pragma once

#include <cstdint>
#include <vector>

namespace mvkp {

// Clusters n points of `dim` floats (row-major) into min(k, n) centres,
// written row-major to `centres`. Deterministic for a given seed.
void KMeans(const float* points, int n, int dim, int k, int iterations, std::uint64_t seed,
            std::vector<float>& centres);

}  // namespace mvkp
