#include "mvkp/detect/detector.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"

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
}

void MinEigen3x3(const cv::Mat& gray, cv::Mat& eig) {
  CV_Assert(gray.type() == CV_8UC1);
  const int W = gray.cols, H = gray.rows;
  eig.create(H, W, CV_32F);
  eig.setTo(0);
  if (W < 5 || H < 5) return;
  // Products of Sobel gradients summed over 3 columns, kept for the last three
  // rows; summing those gives the 3x3 structure tensor. Float arithmetic is
  // exact here (|g| <= 1020, so sums of 9 products stay below 2^24) and
  // vectorises with SSE2, unlike 32-bit integer multiplies.
  std::vector<float> buf(std::size_t(9) * W, 0.f);
  std::vector<float> gx(W), gy(W), pxx(W), pxy(W), pyy(W);
  auto row_of = [&](int r, int k) { return &buf[(std::size_t(r % 3) * 3 + k) * W]; };
  // OpenCV's normalisation for 8-bit input, aperture 3, block 3: 1 / (4 * 3 * 255).
  const float s = 1.f / (4.f * 3.f * 255.f);
  const float s2 = s * s;
  for (int y = 1; y < H - 1; ++y) {
    const std::uint8_t* a = gray.ptr<std::uint8_t>(y - 1);
    const std::uint8_t* b = gray.ptr<std::uint8_t>(y);
    const std::uint8_t* c = gray.ptr<std::uint8_t>(y + 1);
    for (int x = 1; x < W - 1; ++x) {
      gx[x] = float((a[x + 1] - a[x - 1]) + 2 * (b[x + 1] - b[x - 1]) + (c[x + 1] - c[x - 1]));
      gy[x] = float((c[x - 1] - a[x - 1]) + 2 * (c[x] - a[x]) + (c[x + 1] - a[x + 1]));
    }
    for (int x = 1; x < W - 1; ++x) {
      pxx[x] = gx[x] * gx[x];
      pxy[x] = gx[x] * gy[x];
      pyy[x] = gy[x] * gy[x];
    }
    float* hxx = row_of(y, 0);
    float* hxy = row_of(y, 1);
    float* hyy = row_of(y, 2);
    for (int x = 2; x < W - 2; ++x) {
      hxx[x] = pxx[x - 1] + pxx[x] + pxx[x + 1];
      hxy[x] = pxy[x - 1] + pxy[x] + pxy[x + 1];
      hyy[x] = pyy[x - 1] + pyy[x] + pyy[x + 1];
    }
    if (y < 3) continue;
    // Rows y-2, y-1, y are complete: the tensor for row y-1.
    const float *a0 = row_of(y - 2, 0), *a1 = row_of(y - 1, 0), *a2 = row_of(y, 0);
    const float *b0 = row_of(y - 2, 1), *b1 = row_of(y - 1, 1), *b2 = row_of(y, 1);
    const float *c0 = row_of(y - 2, 2), *c1 = row_of(y - 1, 2), *c2 = row_of(y, 2);
    float* out = eig.ptr<float>(y - 1);
    for (int x = 2; x < W - 2; ++x) {
      const float A = (a0[x] + a1[x] + a2[x]) * (0.5f * s2);
      const float B = (b0[x] + b1[x] + b2[x]) * s2;
      const float C = (c0[x] + c1[x] + c2[x]) * (0.5f * s2);
      out[x] = (A + C) - std::sqrt((A - C) * (A - C) + B * B);
    }
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
  double maxv = 0;
  cv::minMaxLoc(eig, nullptr, &maxv, nullptr, nullptr, mask);
  const float thresh = std::max(opt.min_strength, float(maxv) * opt.relative_threshold);
  if (maxv < thresh || maxv <= 0) return out;

  // Local maxima over 3x3: strictly greater than the previous row/left
  // neighbours and not smaller than the following ones, so plateaus give one point.
  std::vector<Keypoint> cand;
  cand.reserve(4096);
  const int b = std::max(opt.border, 1);
  for (int y = b; y < eig.rows - b; ++y) {
    const float* up = eig.ptr<float>(y - 1);
    const float* c = eig.ptr<float>(y);
    const float* dn = eig.ptr<float>(y + 1);
    const std::uint8_t* m = mask.empty() ? nullptr : mask.ptr<std::uint8_t>(y);
    for (int x = b; x < eig.cols - b; ++x) {
      const float v = c[x];
      if (v < thresh) continue;
      if (!(v > c[x - 1] && v >= c[x + 1] && v > up[x - 1] && v > up[x] && v > up[x + 1] && v >= dn[x - 1] &&
            v >= dn[x] && v >= dn[x + 1]))
        continue;
      if (m && !m[x]) continue;
      // Sub-pixel position: vertex of the parabola through the 3 responses per axis.
      const float dxx = c[x - 1] - 2 * v + c[x + 1], dyy = up[x] - 2 * v + dn[x];
      const float ox = dxx < 0 ? std::clamp(0.5f * (c[x - 1] - c[x + 1]) / dxx, -0.5f, 0.5f) : 0.f;
      const float oy = dyy < 0 ? std::clamp(0.5f * (up[x] - dn[x]) / dyy, -0.5f, 0.5f) : 0.f;
      cand.push_back({float(x) + ox, float(y) + oy, v, 0.f});
    }
  }
  std::sort(cand.begin(), cand.end(), [](const Keypoint& a, const Keypoint& b) {
    return a.strength > b.strength || (a.strength == b.strength && (a.y < b.y || (a.y == b.y && a.x < b.x)));
  });

  // Greedy minimum spacing on a grid of cells of side min_distance.
  const float md = opt.min_distance;
  if (md < 1.f) {
    if (int(cand.size()) > opt.max_points) cand.resize(opt.max_points);
    return cand;
  }
  const int cell = std::max(1, int(std::ceil(md)));
  const int gw = (gray.cols + cell - 1) / cell, gh = (gray.rows + cell - 1) / cell;
  std::vector<std::vector<int>> grid(std::size_t(gw) * gh);
  const float md2 = md * md;
  out.reserve(std::min<std::size_t>(cand.size(), opt.max_points));
  for (const auto& k : cand) {
    const int gx = int(k.x) / cell, gy = int(k.y) / cell;
    bool ok = true;
    for (int yy = std::max(0, gy - 1); yy <= std::min(gh - 1, gy + 1) && ok; ++yy)
      for (int xx = std::max(0, gx - 1); xx <= std::min(gw - 1, gx + 1) && ok; ++xx)
        for (int id : grid[std::size_t(yy) * gw + xx]) {
          const float dx = out[id].x - k.x, dy = out[id].y - k.y;
          if (dx * dx + dy * dy < md2) { ok = false; break; }
        }
    if (!ok) continue;
    grid[std::size_t(gy) * gw + gx].push_back(int(out.size()));
    out.push_back(k);
    if (int(out.size()) >= opt.max_points) break;
  }
  return out;
}

}  // namespace mvkp
