#include "mvkp/detect/detector.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/detect/internal/detect_kernels.h"

namespace mvkp {

void DetectorOptions::Check() const {
  Require(max_points >= 1, ErrorCode::kInvalidArgument, "detector: max_points must be >= 1");
  Require(min_strength >= 0.f, ErrorCode::kInvalidArgument, "detector: min_strength must be >= 0");
  Require(relative_threshold >= 0.f && relative_threshold < 1.f, ErrorCode::kInvalidArgument,
          "detector: relative_threshold must be in [0, 1)");
  Require(min_distance >= 0.f && min_distance <= 100.f, ErrorCode::kInvalidArgument,
          "detector: min_distance must be in [0, 100]");
  Require(border >= 1, ErrorCode::kInvalidArgument, "detector: border must be >= 1");
  Require(block_size >= 2 && block_size <= 15, ErrorCode::kInvalidArgument, "detector: block_size must be in 2..15");
  Require(grid_cells >= 1 && grid_cells <= 256, ErrorCode::kInvalidArgument, "detector: grid_cells must be in 1..256");
  Require(grid_share >= 0.f && grid_share <= 1.f, ErrorCode::kInvalidArgument, "detector: grid_share must be in [0, 1]");
}

void MinEigen3x3(const cv::Mat& gray, cv::Mat& eig) {
  CV_Assert(gray.type() == CV_8UC1);
  const int W = gray.cols, H = gray.rows;
  eig.create(H, W, CV_32F);
  if (W < 5 || H < 5) {
    eig.setTo(0);
    return;
  }
  // Only the outermost two rows and columns are not written below.
  eig.rowRange(0, 2).setTo(0);
  eig.rowRange(H - 2, H).setTo(0);
  for (int y = 2; y < H - 2; ++y) {
    float* e = eig.ptr<float>(y);
    e[0] = e[1] = e[W - 2] = e[W - 1] = 0.f;
  }
  // Products of Sobel gradients summed over 3 columns, kept for the last three
  // rows; summing those gives the 3x3 structure tensor. Float arithmetic is
  // exact here (|g| <= 1020, so sums of 9 products stay below 2^24) and
  // vectorises, unlike 32-bit integer multiplies.
  static const internal::GradientRowFn gradient_row = internal::BestGradientRow();
  static const internal::EigenRowFn eigen_row = internal::BestEigenRow();
  std::vector<float> buf(std::size_t(9) * W, 0.f);
  std::vector<float> pxx(W), pxy(W), pyy(W);
  auto row_of = [&](int r, int k) { return &buf[(std::size_t(r % 3) * 3 + k) * W]; };
  // OpenCV's normalisation for 8-bit input, aperture 3, block 3: 1 / (4 * 3 * 255).
  const float s = 1.f / (4.f * 3.f * 255.f);
  const float s2 = s * s;
  for (int y = 1; y < H - 1; ++y) {
    gradient_row(gray.ptr<std::uint8_t>(y - 1), gray.ptr<std::uint8_t>(y), gray.ptr<std::uint8_t>(y + 1), W, pxx.data(),
                 pxy.data(), pyy.data(), row_of(y, 0), row_of(y, 1), row_of(y, 2));
    if (y < 3) continue;
    // Rows y-2, y-1, y are complete: the tensor for row y-1.
    eigen_row(row_of(y - 2, 0), row_of(y - 1, 0), row_of(y, 0), row_of(y - 2, 1), row_of(y - 1, 1), row_of(y, 1),
              row_of(y - 2, 2), row_of(y - 1, 2), row_of(y, 2), 2, W - 2, s2, eig.ptr<float>(y - 1));
  }
}

std::vector<Keypoint> DetectMinEigen(const cv::Mat& gray, const DetectorOptions& opt, const cv::Mat& mask) {
  opt.Check();
  CV_Assert(gray.type() == CV_8UC1);
  CV_Assert(mask.empty() || (mask.type() == CV_8UC1 && mask.size() == gray.size()));
  std::vector<Keypoint> out;
  if (gray.rows <= 2 * opt.border || gray.cols <= 2 * opt.border) return out;

  cv::Mat eig;
  if (opt.block_size == 3)
    MinEigen3x3(gray, eig);
  else
    cv::cornerMinEigenVal(gray, eig, opt.block_size, 3, cv::BORDER_REFLECT_101);
  // The relative threshold: of the frame's strongest response, or with the
  // grid of each cell's, so a dim region in a bright frame keeps its corners.
  const bool by_cell = opt.grid_share > 0 && opt.grid_cells > 1;
  const double cell_side = double(std::max(gray.cols, gray.rows)) / opt.grid_cells;
  const int gcw = by_cell ? std::max(1, int(std::ceil(gray.cols / cell_side))) : 1;
  const int gch = by_cell ? std::max(1, int(std::ceil(gray.rows / cell_side))) : 1;
  // Each cell's strongest response (under the mask), in one pass over the
  // response: cell (cx, cy) spans columns [int(cx * side), int((cx + 1) * side))
  // and the same for rows. The cells cover the frame, so the frame's maximum
  // is theirs. (One cv::minMaxLoc per cell cost more than the detection.)
  std::vector<float> cell_max(std::size_t(gcw) * gch, 0.f);
  std::vector<char> cell_empty(cell_max.size(), 0);  // no pixels (tiny frames): the frame's threshold applies
  double maxv = 0;
  if (by_cell) {
    static const internal::RowMaxFn row_max = internal::BestRowMax();
    std::vector<int> col_end(static_cast<std::size_t>(gcw));
    for (int cx = 0; cx < gcw; ++cx) col_end[cx] = std::min(gray.cols, int((cx + 1) * cell_side));
    for (int cy = 0; cy < gch; ++cy) {
      const int y0 = int(cy * cell_side), y1 = std::min(gray.rows, int((cy + 1) * cell_side));
      float* cm = &cell_max[std::size_t(cy) * gcw];
      for (int cx = 0; cx < gcw; ++cx)
        cell_empty[std::size_t(cy) * gcw + cx] = y1 <= y0 || col_end[cx] <= int(cx * cell_side);
      for (int y = y0; y < y1; ++y) {
        const float* e = eig.ptr<float>(y);
        const std::uint8_t* m = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(y);
        for (int cx = 0; cx < gcw; ++cx) cm[cx] = row_max(e, m, int(cx * cell_side), col_end[cx], cm[cx]);
      }
    }
    for (const float v : cell_max) maxv = std::max(maxv, double(v));
  } else {
    cv::minMaxLoc(eig, nullptr, &maxv, nullptr, nullptr, mask);
  }
  if (maxv < opt.min_strength || maxv <= 0) return out;
  std::vector<float> cell_thresh(std::size_t(gcw) * gch, std::max(opt.min_strength, float(maxv) * opt.relative_threshold));
  float thresh = cell_thresh[0];
  if (by_cell) {
    thresh = opt.min_strength;
    for (std::size_t i = 0; i < cell_max.size(); ++i) {
      if (cell_empty[i]) {
        cell_max[i] = float(maxv);
        continue;
      }
      cell_thresh[i] = std::max(opt.min_strength, cell_max[i] * opt.relative_threshold);
      cell_max[i] = std::max(cell_max[i], 1e-12f);
    }
  } else {
    cell_max.assign(cell_max.size(), float(maxv));
  }

  // Local maxima over 3x3: strictly greater than the previous row/left
  // neighbours and not smaller than the following ones, so plateaus give one point.
  static const internal::NmsRowFn nms_row = internal::BestNmsRow();
  std::vector<Keypoint> cand;
  cand.reserve(4096);
  std::vector<int> cols;
  cols.reserve(std::size_t(gray.cols));
  const int b = std::max(opt.border, 1);
  for (int y = b; y < eig.rows - b; ++y) {
    const float* up = eig.ptr<float>(y - 1);
    const float* c = eig.ptr<float>(y);
    const float* dn = eig.ptr<float>(y + 1);
    const std::uint8_t* m = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(y);
    cols.clear();
    nms_row(up, c, dn, b, eig.cols - b, thresh, cols);
    const int cy = by_cell ? std::min(gch - 1, int(y / cell_side)) : 0;
    for (const int x : cols) {
      if (m && !m[x]) continue;
      const float v = c[x];
      if (by_cell && v < cell_thresh[std::size_t(cy) * gcw + std::min(gcw - 1, int(x / cell_side))]) continue;
      // Sub-pixel position: vertex of the parabola through the 3 responses per axis.
      const float dxx = c[x - 1] - 2 * v + c[x + 1], dyy = up[x] - 2 * v + dn[x];
      const float ox = dxx < 0 ? std::clamp(0.5f * (c[x - 1] - c[x + 1]) / dxx, -0.5f, 0.5f) : 0.f;
      const float oy = dyy < 0 ? std::clamp(0.5f * (up[x] - dn[x]) / dyy, -0.5f, 0.5f) : 0.f;
      cand.push_back({float(x) + ox, float(y) + oy, v, 0.f});
    }
  }
  // Strongest first, ties by (y, x). Sorted by (inverted strength bits,
  // candidate index): strengths are >= 0, so their bit patterns order as the
  // values do; then runs of equal strength by (y, x).
  const auto by_order = [](const Keypoint& a, const Keypoint& b) {
    return a.strength > b.strength || (a.strength == b.strength && (a.y < b.y || (a.y == b.y && a.x < b.x)));
  };
  {
    // The keys' order is (inverted strength bits, index): a stable radix
    // sort of the indices on the 32 strength bits, three 11-bit digits,
    // gives it without a comparison.
    const std::size_t n = cand.size();
    std::vector<std::uint32_t> key(n), idx(n), key2(n), idx2(n);
    for (std::size_t i = 0; i < n; ++i) {
      const float v = cand[i].strength + 0.f;  // >= 0 (thresholds are); -0 becomes +0
      std::uint32_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      key[i] = ~bits;
      idx[i] = std::uint32_t(i);
    }
    for (int shift = 0; shift < 32; shift += 11) {
      std::uint32_t count[2049] = {};
      for (std::size_t i = 0; i < n; ++i) ++count[((key[i] >> shift) & 2047u) + 1];
      for (int d = 0; d < 2048; ++d) count[d + 1] += count[d];
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t pos = count[(key[i] >> shift) & 2047u]++;
        key2[pos] = key[i];
        idx2[pos] = idx[i];
      }
      key.swap(key2);
      idx.swap(idx2);
    }
    std::vector<Keypoint> sorted(n);
    for (std::size_t i = 0; i < n; ++i) sorted[i] = cand[idx[i]];
    for (std::size_t i = 0; i < sorted.size();) {
      std::size_t j = i + 1;
      while (j < sorted.size() && sorted[j].strength == sorted[i].strength) ++j;
      if (j - i > 1) std::sort(sorted.begin() + std::ptrdiff_t(i), sorted.begin() + std::ptrdiff_t(j), by_order);
      i = j;
    }
    cand = std::move(sorted);
  }

  // Greedy minimum spacing on a grid of cells of side min_distance, first
  // with a quota per coarse cell, then for the rest of the budget.
  const float md = std::max(opt.min_distance, 0.f);
  const int cell = std::max(1, int(std::ceil(md)));
  const int gw = (gray.cols + cell - 1) / cell, gh = (gray.rows + cell - 1) / cell;
  // Chosen points per cell as linked lists (head per cell, next per
  // candidate): one flat array instead of a vector per cell, of which a
  // 640x480 frame has 34000 at the default spacing.
  std::vector<int> head(md >= 1.f ? std::size_t(gw) * gh : 0, -1), next_in_cell(md >= 1.f ? cand.size() : 0, -1);
  const float md2 = md * md;
  std::vector<char> taken(cand.size(), 0);
  std::vector<int> chosen;
  chosen.reserve(std::min<std::size_t>(cand.size(), opt.max_points));
  auto spaced = [&](const Keypoint& k) {
    if (md < 1.f) return true;
    const int gx = int(k.x) / cell, gy = int(k.y) / cell;
    for (int yy = std::max(0, gy - 1); yy <= std::min(gh - 1, gy + 1); ++yy)
      for (int xx = std::max(0, gx - 1); xx <= std::min(gw - 1, gx + 1); ++xx)
        for (int id = head[std::size_t(yy) * gw + xx]; id >= 0; id = next_in_cell[std::size_t(id)]) {
          const float dx = cand[id].x - k.x, dy = cand[id].y - k.y;
          if (dx * dx + dy * dy < md2) return false;
        }
    return true;
  };
  auto take = [&](int i) {
    taken[i] = 1;
    chosen.push_back(i);
    if (md >= 1.f) {
      int& h = head[std::size_t(int(cand[i].y) / cell) * gw + int(cand[i].x) / cell];
      next_in_cell[std::size_t(i)] = h;
      h = i;
    }
  };
  const int budget = opt.max_points;
  const int quota_total = int(std::lround(double(opt.grid_share) * budget));
  if (quota_total > 0 && opt.grid_cells > 1) {
    const double side = double(std::max(gray.cols, gray.rows)) / opt.grid_cells;
    const int cw = std::max(1, int(std::ceil(gray.cols / side))), ch = std::max(1, int(std::ceil(gray.rows / side)));
    // Round by round: every cell's strongest, then every cell's next, ...;
    // within a round, strongest relative to its own cell first. A cell of
    // weak corners gets its turn however strong the others are.
    std::vector<std::vector<int>> bucket(std::size_t(cw) * ch);
    for (int i = 0; i < int(cand.size()); ++i) {
      const int cx = std::min(cw - 1, int(cand[i].x / side)), cy = std::min(ch - 1, int(cand[i].y / side));
      bucket[std::size_t(cy) * cw + cx].push_back(i);
    }
    std::vector<std::size_t> next(bucket.size(), 0);
    std::vector<int> round;
    std::vector<std::pair<float, int>> rel_round;
    while (int(chosen.size()) < quota_total) {
      round.clear();
      for (std::size_t b = 0; b < bucket.size(); ++b) {
        // The cell's next candidate that keeps the spacing.
        while (next[b] < bucket[b].size() && !spaced(cand[bucket[b][next[b]]])) ++next[b];
        if (next[b] < bucket[b].size()) round.push_back(bucket[b][next[b]++]);
      }
      if (round.empty()) break;
      // Each point's strength relative to its cell, computed once (not per
      // comparison), then a stable sort by it: the same order as before.
      rel_round.clear();
      for (const int i : round) {
        const int cx = std::min(cw - 1, int(cand[i].x / side)), cy = std::min(ch - 1, int(cand[i].y / side));
        rel_round.push_back({cand[i].strength / cell_max[std::size_t(cy) * cw + cx], i});
      }
      std::stable_sort(rel_round.begin(), rel_round.end(),
                       [](const std::pair<float, int>& a, const std::pair<float, int>& b) { return a.first > b.first; });
      for (std::size_t k = 0; k < rel_round.size(); ++k) round[k] = rel_round[k].second;
      for (int i : round) {
        if (int(chosen.size()) >= quota_total) break;
        if (spaced(cand[i])) take(i);
      }
    }
  }
  for (int i = 0; i < int(cand.size()) && int(chosen.size()) < budget; ++i)
    if (!taken[i] && spaced(cand[i])) take(i);
  std::sort(chosen.begin(), chosen.end());  // candidates are strongest first
  out.reserve(chosen.size());
  for (int i : chosen) out.push_back(cand[i]);
  return out;
}

}  // namespace mvkp
