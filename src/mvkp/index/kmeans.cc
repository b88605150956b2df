#include "mvkp/index/kmeans.h"

#include <algorithm>
#include <limits>
#include <random>

namespace mvkp {
namespace {

float Dist2(const float* a, const float* b, int dim) {
  float s = 0.f;
  for (int d = 0; d < dim; ++d) {
    const float t = a[d] - b[d];
    s += t * t;
  }
  return s;
}

}  // namespace

void KMeans(const float* pts, int n, int dim, int k, int iterations, std::uint64_t seed, std::vector<float>& centres) {
  k = std::min(k, n);
  centres.assign(std::size_t(k) * dim, 0.f);
  if (k <= 0) return;
  if (k == n) {
    std::copy(pts, pts + std::size_t(n) * dim, centres.begin());
    return;
  }
  std::mt19937_64 rng(seed);
  // k-means++ seeding.
  std::vector<float> best(n, std::numeric_limits<float>::max());
  int first = int(std::uniform_int_distribution<int>(0, n - 1)(rng));
  std::copy(pts + std::size_t(first) * dim, pts + std::size_t(first + 1) * dim, centres.begin());
  for (int c = 1; c < k; ++c) {
    double total = 0;
    for (int i = 0; i < n; ++i) {
      best[i] = std::min(best[i], Dist2(pts + std::size_t(i) * dim, &centres[std::size_t(c - 1) * dim], dim));
      total += best[i];
    }
    int pick = n - 1;
    if (total > 0) {
      double r = std::uniform_real_distribution<double>(0.0, total)(rng);
      for (int i = 0; i < n; ++i) {
        r -= best[i];
        if (r <= 0) { pick = i; break; }
      }
    } else {
      pick = int(std::uniform_int_distribution<int>(0, n - 1)(rng));
    }
    std::copy(pts + std::size_t(pick) * dim, pts + std::size_t(pick + 1) * dim, centres.begin() + std::size_t(c) * dim);
  }
  // Lloyd iterations.
  std::vector<int> assign(n, -1);
  std::vector<double> sum(std::size_t(k) * dim);
  std::vector<int> count(k);
  for (int it = 0; it < iterations; ++it) {
    bool changed = false;
    for (int i = 0; i < n; ++i) {
      int arg = 0;
      float bd = std::numeric_limits<float>::max();
      for (int c = 0; c < k; ++c) {
        const float d = Dist2(pts + std::size_t(i) * dim, &centres[std::size_t(c) * dim], dim);
        if (d < bd) { bd = d; arg = c; }
      }
      if (assign[i] != arg) { assign[i] = arg; changed = true; }
    }
    if (!changed) break;
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (int i = 0; i < n; ++i) {
      ++count[assign[i]];
      for (int d = 0; d < dim; ++d) sum[std::size_t(assign[i]) * dim + d] += pts[std::size_t(i) * dim + d];
    }
    for (int c = 0; c < k; ++c)
      if (count[c] > 0)
        for (int d = 0; d < dim; ++d) centres[std::size_t(c) * dim + d] = float(sum[std::size_t(c) * dim + d] / count[c]);
  }
}

}  // namespace mvkp
