#include "mvkp/index/ivf.h"

#include <algorithm>
#include <atomic>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp {

using internal::kLanes;

void IvfOptions::Check() const { Require(nprobe >= 1, ErrorCode::kInvalidArgument, "ivf: nprobe must be >= 1"); }

struct IvfIndex::Impl {
  std::size_t ncentroids = 0;
  std::unique_ptr<KnnIndex> coarse;  // exact FFVA over the centroids
  // The lists, one after the other, each padded to whole blocks of 8 vectors.
  std::vector<std::size_t> first_block;  // per list, and one past the last
  std::vector<float> blocks;             // block[d * 8 + lane]
  std::vector<float> norms;              // |x|^2 per lane, +inf for padding
  std::vector<std::int32_t> labels;      // per lane, -1 for padding
  std::vector<std::int32_t> rows;        // per lane: row in Build's data, -1 for padding
  internal::TwoDistinctNormFn two = nullptr;
  internal::L2Blocks8Fn l2 = nullptr;
  // A few hundred centroids: scanned directly (row-major copy), see Probe.
  std::vector<float> centroids;
  int dim = 0;
  internal::NearestRowsFn nearest = nullptr;
  mutable std::atomic<std::uint64_t> computations{0};

  // The probed lists of nq queries: nq * nprobe list numbers.
  std::vector<std::int32_t> Probe(const float* queries, std::size_t nq, int nprobe) const {
    if (nearest && nprobe <= internal::kMaxNearest) {
      // The same lists as the brute-force scan below, without its branches.
      std::vector<std::int32_t> cells(nq * std::size_t(nprobe));
      if (nq) nearest(centroids.data(), ncentroids, dim, queries, nq, nprobe, cells.data());
      return cells;
    }
    std::vector<Neighbor> nn(nq * std::size_t(nprobe));
    if (nq) coarse->SearchBatch(queries, nq, nprobe, nn.data());
    std::vector<std::int32_t> cells(nn.size());
    for (std::size_t i = 0; i < nn.size(); ++i) cells[i] = nn[i].id;
    return cells;
  }
};

IvfIndex::IvfIndex(const float* centroids, std::size_t ncentroids, int dim, const IvfOptions& options)
    : impl_(std::make_unique<Impl>()), options_(options) {
  options_.Check();
  Require(ncentroids >= 1 && dim >= 1, ErrorCode::kInvalidArgument, "ivf: needs centroids of dimension >= 1");
  Require(ncentroids < std::size_t(std::numeric_limits<std::int32_t>::max()), ErrorCode::kInvalidArgument,
          "ivf: too many centroids");
  internal::RequireFinite(centroids, ncentroids, dim, "ivf: centroids");
  options_.nprobe = std::min<int>(options_.nprobe, int(ncentroids));
  dim_ = dim;
  impl_->ncentroids = ncentroids;
  std::vector<std::int32_t> ids(ncentroids);
  std::iota(ids.begin(), ids.end(), 0);
  // A few hundred centroids are scanned faster than FFVA's tree is walked.
  impl_->coarse = ncentroids <= 256 ? MakeBruteForceIndex() : MakeIndexByName("exact");
  if (ncentroids <= 256) {
    impl_->centroids.assign(centroids, centroids + ncentroids * std::size_t(dim));
    impl_->dim = dim;
    impl_->nearest = internal::BestNearestRows();
  }
  impl_->coarse->Build(centroids, ncentroids, dim, ids.data());
  impl_->two = internal::BestTwoDistinctNorm();
  impl_->l2 = internal::BestL2Blocks8();
  impl_->first_block.assign(ncentroids + 1, 0);
}

IvfIndex::~IvfIndex() = default;

void IvfIndex::Assign(const float* data, std::size_t n, std::int32_t* cells) const {
  internal::RequireFinite(data, n, dim_, "ivf: vectors");
  const std::vector<std::int32_t> c = impl_->Probe(data, n, 1);
  std::copy(c.begin(), c.end(), cells);
}

void IvfIndex::Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) {
  Require(dim == dim_, ErrorCode::kInvalidArgument, "ivf: data dimension differs from the centroids'");
  std::vector<std::int32_t> cells(n);
  Assign(data, n, cells.data());
  BuildAssigned(data, n, dim, labels, cells.data());
}

void IvfIndex::BuildAssigned(const float* data, std::size_t n, int dim, const std::int32_t* labels,
                             const std::int32_t* cells) {
  Require(dim == dim_, ErrorCode::kInvalidArgument, "ivf: data dimension differs from the centroids'");
  Require(n < std::size_t(std::numeric_limits<std::int32_t>::max()), ErrorCode::kInvalidArgument,
          "ivf: too many vectors");
  internal::RequireFinite(data, n, dim, "ivf: database");
  Impl& im = *impl_;
  const std::size_t C = im.ncentroids;
  std::vector<std::size_t> count(C, 0);
  for (std::size_t i = 0; i < n; ++i) {
    Require(cells[i] >= 0 && std::size_t(cells[i]) < C, ErrorCode::kInvalidArgument, "ivf: cell out of range");
    ++count[std::size_t(cells[i])];
  }
  im.first_block.assign(C + 1, 0);
  for (std::size_t c = 0; c < C; ++c) im.first_block[c + 1] = im.first_block[c] + (count[c] + kLanes - 1) / kLanes;
  const std::size_t nblocks = im.first_block[C];
  im.blocks.assign(nblocks * std::size_t(dim) * kLanes, 1e18f);
  im.norms.assign(nblocks * kLanes, std::numeric_limits<float>::infinity());
  im.labels.assign(nblocks * kLanes, -1);
  im.rows.assign(nblocks * kLanes, -1);
  std::vector<std::size_t> fill(C, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t c = std::size_t(cells[i]);
    const std::size_t lane = im.first_block[c] * kLanes + fill[c]++;
    const std::size_t b = lane / kLanes, l = lane % kLanes;
    const float* x = data + i * std::size_t(dim);
    for (int d = 0; d < dim; ++d) im.blocks[(b * std::size_t(dim) + std::size_t(d)) * kLanes + l] = x[d];
    im.norms[lane] = internal::SquaredNorm(x, dim);
    im.labels[lane] = labels[i];
    im.rows[lane] = std::int32_t(i);
  }
  n_ = n;
}

void IvfIndex::Search(const float* query, int k, Neighbor* out) const {
  Require(k >= 1, ErrorCode::kInvalidArgument, "ivf: k must be >= 1");
  internal::RequireFinite(query, 1, dim_, "ivf: query");
  const Impl& im = *impl_;
  std::vector<Neighbor> cand;
  std::vector<float> d;
  for (const std::int32_t c : im.Probe(query, 1, options_.nprobe)) {
    if (c < 0) continue;
    const std::size_t b0 = im.first_block[std::size_t(c)], nb = im.first_block[std::size_t(c) + 1] - b0;
    if (!nb) continue;
    d.resize(nb * kLanes);
    im.l2(im.blocks.data() + b0 * std::size_t(dim_) * kLanes, nb, query, dim_, d.data());
    im.computations.fetch_add(nb * kLanes, std::memory_order_relaxed);
    for (std::size_t j = 0; j < nb * kLanes; ++j) {
      const std::int32_t row = im.rows[b0 * kLanes + j];
      if (row >= 0) cand.push_back({row, im.labels[b0 * kLanes + j], d[j]});
    }
  }
  const auto less = [](const Neighbor& a, const Neighbor& b) {
    return a.distance < b.distance || (a.distance == b.distance && a.id < b.id);
  };
  const std::size_t m = std::min<std::size_t>(std::size_t(k), cand.size());
  std::partial_sort(cand.begin(), cand.begin() + std::ptrdiff_t(m), cand.end(), less);
  for (int i = 0; i < k; ++i) out[i] = std::size_t(i) < m ? cand[std::size_t(i)] : Neighbor{};
}

void IvfIndex::SearchTwoDistinct(const float* query, Neighbor out[2], float ratio) const {
  SearchTwoDistinctBatch(query, 1, out, ratio);
}

// Queries are grouped by probed list; each list is scanned once per group of
// up to four queries (the brute-force kernel), then each query's list-local
// top two are offered to its running top two. The merge is exact: the overall
// nearest is some list's nearest, and the nearest with another label is, in
// its list, that list's nearest or its nearest with another label.
void IvfIndex::SearchTwoDistinctBatch(const float* queries, std::size_t nq, Neighbor* out, float ratio) const {
  internal::RequireFinite(queries, nq, dim_, "ivf: query");
  const Impl& im = *impl_;
  const int P = options_.nprobe;
  const std::vector<std::int32_t> cells = im.Probe(queries, nq, P);
  // Counting sort of (list, query) pairs by list.
  const std::size_t C = im.ncentroids;
  std::vector<std::uint32_t> start(C + 1, 0);
  for (const std::int32_t c : cells)
    if (c >= 0) ++start[std::size_t(c) + 1];
  for (std::size_t c = 0; c < C; ++c) start[c + 1] += start[c];
  std::vector<std::uint32_t> by_list(start[C]);
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < cells.size(); ++i)
      if (cells[i] >= 0) by_list[fill[std::size_t(cells[i])]++] = std::uint32_t(i / std::size_t(P));
  }
  // No pruning by `ratio`: skipping rows saves no distance computation in the
  // kernel, and without it out[1] is the true second neighbour within the
  // probed lists, so a caller ranking matches by their ratio (the
  // recogniser's dynamic ratio) sees real ratios, not 0 for "far enough".
  (void)ratio;
  std::vector<internal::TopTwo> best(nq, internal::EmptyTopTwo(0.f));
  std::vector<float> qnorm(nq);
  for (std::size_t i = 0; i < nq; ++i) qnorm[i] = internal::SquaredNorm(queries + i * std::size_t(dim_), dim_);
  std::vector<float> q4(4 * std::size_t(dim_));
  std::uint64_t computed = 0;
  for (std::size_t c = 0; c < C; ++c) {
    const std::size_t b0 = im.first_block[c], nb = im.first_block[c + 1] - b0;
    if (!nb) continue;
    const float* blk = im.blocks.data() + b0 * std::size_t(dim_) * kLanes;
    const float* nrm = im.norms.data() + b0 * kLanes;
    const std::int32_t* lab = im.labels.data() + b0 * kLanes;
    const std::int32_t* row = im.rows.data() + b0 * kLanes;
    for (std::uint32_t g = start[c]; g < start[c + 1]; g += 4) {
      const int m = int(std::min<std::uint32_t>(4, start[c + 1] - g));
      internal::TopTwo t[4];
      float qn[4];
      for (int k = 0; k < m; ++k) {
        const std::uint32_t q = by_list[g + std::uint32_t(k)];
        std::copy_n(queries + std::size_t(q) * std::size_t(dim_), dim_, q4.data() + std::size_t(k) * std::size_t(dim_));
        qn[k] = qnorm[q];
        // Start from the query's running distances so the kernel keeps only
        // what improves them (ids -1: only the distances and the label steer it).
        t[k] = best[q];
        t[k].id1 = t[k].id2 = -1;
      }
      im.two(blk, nrm, lab, nb, q4.data(), qn, m, dim_, t);
      computed += nb * kLanes * std::size_t(m);
      for (int k = 0; k < m; ++k) {
        internal::TopTwo& b = best[by_list[g + std::uint32_t(k)]];
        // Entries with id >= 0 came from this list (list-local lane numbers).
        const internal::TopTwo& x = t[k];
        if (x.id1 >= 0) internal::TopTwoOffer(b, x.d1, row[x.id1], x.lab1);
        if (x.id2 >= 0) internal::TopTwoOffer(b, x.d2, row[x.id2], x.lab2);
      }
    }
  }
  im.computations.fetch_add(computed, std::memory_order_relaxed);
  for (std::size_t i = 0; i < nq; ++i) {
    const internal::TopTwo& t = best[i];
    out[2 * i] = t.id1 < 0 ? Neighbor{} : Neighbor{t.id1, t.lab1, t.d1};
    out[2 * i + 1] = t.id2 < 0 ? Neighbor{} : Neighbor{t.id2, t.lab2, t.d2};
  }
}

std::uint64_t IvfIndex::distance_computations() const { return impl_->computations.load(); }
void IvfIndex::ResetStats() const { impl_->computations = 0; }

std::size_t IvfIndex::memory_bytes() const {
  const Impl& im = *impl_;
  return sizeof(*this) + sizeof(Impl) + im.coarse->memory_bytes() + im.first_block.capacity() * sizeof(std::size_t) +
         im.blocks.capacity() * sizeof(float) + im.norms.capacity() * sizeof(float) +
         (im.labels.capacity() + im.rows.capacity()) * sizeof(std::int32_t);
}

}  // namespace mvkp
