#include "datasets.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"

namespace mvkp::bench {
namespace {

constexpr int kQueryEvery = 10;      // every 10th source image feeds the query pool
constexpr int kMaxRounds = 100000;   // guards against images without features
constexpr int kBorderMargin = 20;    // px of the warped image's edge excluded from detection

// Round 0 is the image itself; round r >= 1 rotates about the centre by
// r x 137.5 degrees (the golden angle, so angles never repeat) and scales by
// 0.6 .. 1.4 (golden-ratio sequence), keeping the frame size. mask marks the
// pixels that came from inside the original, minus a margin, so that the
// artificial edge of the warp yields no keypoints.
cv::Mat Variant(const cv::Mat& gray, int round, cv::Mat& mask) {
  mask.release();
  if (round == 0) return gray;
  const double angle = std::fmod(round * 137.50776405, 360.0);
  const double scale = 0.6 + 0.8 * std::fmod(round * 0.61803398875, 1.0);
  const cv::Mat a = cv::getRotationMatrix2D(cv::Point2f(gray.cols * 0.5f, gray.rows * 0.5f), angle, scale);
  cv::Mat out;
  cv::warpAffine(gray, out, a, gray.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::warpAffine(cv::Mat(gray.size(), CV_8UC1, cv::Scalar(255)), mask, a, gray.size(), cv::INTER_NEAREST,
                 cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * kBorderMargin + 1, 2 * kBorderMargin + 1)));
  return out;
}

void Append(std::vector<float>& pool, const cv::Mat& desc) {
  if (desc.empty()) return;
  CV_Assert(desc.type() == CV_32F && desc.isContinuous());
  pool.insert(pool.end(), desc.ptr<float>(), desc.ptr<float>() + desc.total());
}

// m rows drawn at random from the pool (rows of dim floats), in pool order.
VectorSet Sample(const std::vector<float>& pool, int dim, std::size_t m, std::mt19937& rng) {
  const std::size_t rows = pool.size() / std::size_t(dim);
  std::vector<std::size_t> idx(rows);
  std::iota(idx.begin(), idx.end(), 0);
  std::shuffle(idx.begin(), idx.end(), rng);
  idx.resize(m);
  std::sort(idx.begin(), idx.end());
  VectorSet s;
  s.dim = dim;
  s.n = m;
  s.data.resize(m * std::size_t(dim));
  for (std::size_t i = 0; i < m; ++i)
    std::copy_n(pool.begin() + std::ptrdiff_t(idx[i] * dim), dim, s.data.begin() + std::ptrdiff_t(i * dim));
  return s;
}

VectorSet Project(const cv::PCA& pca, const VectorSet& in) {
  const cv::Mat x(int(in.n), in.dim, CV_32F, const_cast<float*>(in.data.data()));
  cv::Mat y = pca.project(x);
  y.convertTo(y, CV_32F);
  VectorSet out;
  out.dim = y.cols;
  out.n = in.n;
  out.data.assign(y.ptr<float>(), y.ptr<float>() + y.total());
  return out;
}

}  // namespace

Dataset RandomDataset(std::size_t n, int dim, std::size_t nq, std::uint32_t seed) {
  Require(n >= 1 && nq >= 1 && dim >= 1, ErrorCode::kInvalidArgument, "--random: N, DIM and --nq must be >= 1");
  Timer t;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Dataset d;
  d.db = {dim, n, std::vector<float>(n * std::size_t(dim))};
  d.queries = {dim, nq, std::vector<float>(nq * std::size_t(dim))};
  for (auto& v : d.db.data) v = u(rng);
  for (auto& v : d.queries.data) v = u(rng);
  d.source = "random uniform [0,1)^" + std::to_string(dim) + ", seed " + std::to_string(seed);
  d.generate_ms = t.ElapsedMs();
  return d;
}

Dataset ImageDataset(Descriptor kind, const std::vector<std::string>& images, std::size_t n, std::size_t nq, int dim,
                     std::uint32_t seed) {
  Require(!images.empty(), ErrorCode::kInvalidArgument, "no images given");
  Require(n >= 1 && nq >= 1, ErrorCode::kInvalidArgument, "--n and --nq must be >= 1");
  if (kind == Descriptor::kSift)
    Require(dim == 128 || dim == 64, ErrorCode::kInvalidArgument, "--dim must be 128 or 64 for SIFT");
  Timer t;
  std::vector<cv::Mat> grays;
  for (const auto& path : images) grays.push_back(LoadImageGray(path));

  const FeatureOptions options;  // the defaults the product uses
  const cv::Ptr<cv::SIFT> sift = kind == Descriptor::kSift ? cv::SIFT::create() : nullptr;
  const int raw_dim = kind == Descriptor::kSift ? 128 : options.describer.dims;
  std::vector<float> db_pool, q_pool;
  auto rows = [&](const std::vector<float>& p) { return p.size() / std::size_t(raw_dim); };
  int rounds = 0;
  for (; rows(db_pool) < n || rows(q_pool) < nq; ++rounds) {
    Require(rounds < kMaxRounds, ErrorCode::kInvalidArgument, "the images yield too few descriptors");
    const std::size_t before = db_pool.size() + q_pool.size();
    for (std::size_t i = 0; i < grays.size(); ++i) {
      cv::Mat mask;
      const cv::Mat img = Variant(grays[i], rounds, mask);
      cv::Mat desc;
      if (kind == Descriptor::kWh) {
        desc = ExtractFeatures(img, options, mask).descriptors;
      } else {
        std::vector<cv::KeyPoint> kps;
        sift->detectAndCompute(img, mask, kps, desc);
      }
      const std::size_t source = std::size_t(rounds) * grays.size() + i;
      Append(source % kQueryEvery == kQueryEvery - 1 ? q_pool : db_pool, desc);
    }
    Require(db_pool.size() + q_pool.size() > before, ErrorCode::kInvalidArgument,
            "the images yield no descriptors (round " + std::to_string(rounds) + ")");
    std::fprintf(stderr, "  round %d: %zu database / %zu query descriptors (%.1f s)\n", rounds, rows(db_pool),
                 rows(q_pool), t.ElapsedMs() / 1000);
  }

  std::mt19937 rng(seed);
  Dataset d;
  d.db = Sample(db_pool, raw_dim, n, rng);
  d.queries = Sample(q_pool, raw_dim, nq, rng);
  const std::size_t db_pool_rows = rows(db_pool), q_pool_rows = rows(q_pool);
  std::vector<float>().swap(db_pool);
  std::vector<float>().swap(q_pool);
  std::string what = kind == Descriptor::kWh ? "mvkp WH " + std::to_string(raw_dim) + "-D (default FeatureOptions)"
                                             : std::string("OpenCV SIFT 128-D");
  if (kind == Descriptor::kSift && dim == 64) {
    const std::size_t fit_rows = std::min<std::size_t>(d.db.n, 200000);  // PCA fit on (a sample of) the database
    std::mt19937 fit_rng(seed + 1);
    const VectorSet fit = fit_rows == d.db.n ? d.db : Sample(d.db.data, 128, fit_rows, fit_rng);
    const cv::PCA pca(cv::Mat(int(fit.n), 128, CV_32F, const_cast<float*>(fit.data.data())), cv::noArray(),
                      cv::PCA::DATA_AS_ROW, 64);
    d.db = Project(pca, d.db);
    d.queries = Project(pca, d.queries);
    what = "OpenCV SIFT, PCA 128->64 fitted on " + std::to_string(fit_rows) + " database vectors";
  }
  d.source = what + " from " + std::to_string(grays.size()) + " images x " + std::to_string(rounds) +
             " variants (original, then rotated/scaled copies); pools " + std::to_string(db_pool_rows) + " db / " +
             std::to_string(q_pool_rows) + " query (every " + std::to_string(kQueryEvery) +
             "th source image held out for queries)";
  d.generate_ms = t.ElapsedMs();
  return d;
}

}  // namespace mvkp::bench
