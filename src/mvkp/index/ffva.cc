#include "mvkp/index/ffva.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <vector>

#include "mvkp/core/atomic_file.h"
#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/index/internal/ffva_kernels.h"
#include "mvkp/index/internal/l2_kernels.h"

namespace mvkp {
namespace {

using internal::kBlockLanes;

constexpr char kMagic[8] = {'M', 'V', 'K', 'P', 'F', 'F', 'V', 'A'};
constexpr std::uint32_t kFormatVersion = 1;
constexpr int kCells = 16;              // 4-bit codes
constexpr int kEdges = kCells - 1;      // interior cell boundaries per dimension
constexpr int kBounds = kCells + 1;     // stored boundaries per dimension: -inf, 15 edges, +inf
constexpr int kGroup = internal::kLanes;  // exact distances are computed 8 vectors at a time
constexpr std::size_t kAlign = 64;
constexpr int kMaxDepth = 64;           // kd depth; a balanced tree of 2^31 vectors needs < 31
// Relative safety margin on every lower bound: float rounding in the bound and
// in the exact distance is < 1e-6 relative at the dimensions we support.
constexpr float kShrink = 1.f - 1e-4f;
// Scale of the byte tables: the current threshold maps to this many units.
constexpr float kThresholdUnits = 200.f;

// Fixed-size file header; the in-memory index is the file image, so the
// header sits at offset 0 of both.
struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t header_bytes;
  std::uint64_t file_bytes;
  std::uint64_t n;
  std::uint64_t nblocks;
  std::uint32_t dim;
  std::uint32_t npairs;
  std::uint32_t nnodes;
  std::uint32_t nleaves;
  std::uint32_t leaf_size;
  std::uint32_t filter;  // 0 exact, 1 approx
  std::uint32_t has_labels;
  std::uint32_t reserved;
  std::uint64_t off_cells, off_corners, off_nodes, off_leaves, off_boxes, off_codes, off_vectors, off_ids,
      off_labels;
  std::uint32_t payload_crc;  // CRC-32 of bytes [header_bytes, file_bytes)
  std::uint32_t header_crc;   // CRC-32 of the header up to this field
};
constexpr std::size_t kHeaderBytes = 256;
static_assert(sizeof(Header) <= kHeaderBytes);

// kd-tree node. Internal: dim >= 0, children a (values <= split) and b
// (values >= split), both with larger indices than the node (preorder).
// Leaf: dim == -1, a = leaf number.
struct Node {
  std::int32_t dim;
  float split;
  std::int32_t a, b;
  std::uint32_t first_block, nblocks;  // the subtree's code blocks (contiguous)
};

struct Leaf {
  std::uint32_t first;        // first vector (in stored order)
  std::uint32_t count;        // vectors in the leaf, >= 1
  std::uint32_t first_block;  // first code block
  std::uint32_t reserved;
};

std::size_t AlignUp(std::size_t x) { return (x + kAlign - 1) / kAlign * kAlign; }

[[noreturn]] void BadIndex(const std::string& name, const std::string& what) {
  throw Error(ErrorCode::kBadIndex, name + ": " + what);
}

// Byte storage that is either owned (64-byte aligned) or a read-only mapping.
class Storage {
 public:
  Storage() = default;
  Storage(const Storage&) = delete;
  Storage& operator=(const Storage&) = delete;
  Storage(Storage&& o) noexcept { Swap(o); }
  Storage& operator=(Storage&& o) noexcept {
    if (this != &o) {
      Release();
      Swap(o);
    }
    return *this;
  }
  ~Storage() { Release(); }

  void Allocate(std::size_t bytes) {
    Release();
    owned_ = static_cast<std::uint8_t*>(std::aligned_alloc(kAlign, AlignUp(std::max<std::size_t>(bytes, 1))));
    if (!owned_) throw std::bad_alloc();
    std::memset(owned_, 0, bytes);
    data_ = owned_;
    size_ = bytes;
  }
  void Map(void* p, std::size_t bytes) {
    Release();
    mapped_ = p;
    data_ = static_cast<std::uint8_t*>(p);
    size_ = bytes;
  }
  std::uint8_t* mutable_data() { return owned_; }
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool mapped() const { return mapped_ != nullptr; }

 private:
  void Swap(Storage& o) noexcept {
    std::swap(owned_, o.owned_);
    std::swap(mapped_, o.mapped_);
    std::swap(data_, o.data_);
    std::swap(size_, o.size_);
  }
  void Release() {
    std::free(owned_);
    if (mapped_) munmap(mapped_, size_);
    owned_ = nullptr;
    mapped_ = nullptr;
    data_ = nullptr;
    size_ = 0;
  }
  std::uint8_t* owned_ = nullptr;
  void* mapped_ = nullptr;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

// ---- searching ------------------------------------------------------------

// (distance, id) order: ties go to the smaller id, as in a brute-force scan.
inline bool Less(float d, std::int32_t id, float d2, std::int32_t id2) { return d < d2 || (d == d2 && id < id2); }

struct KnnCollector {
  Neighbor* out;
  int k;
  int filled = 0;
  float Threshold() const { return filled < k ? std::numeric_limits<float>::infinity() : out[k - 1].distance; }
  void Offer(float d, std::int32_t id, std::int32_t label) {
    if (filled == k && !Less(d, id, out[k - 1].distance, out[k - 1].id)) return;
    int p = filled < k ? filled++ : k - 1;
    while (p > 0 && Less(d, id, out[p - 1].distance, out[p - 1].id)) {
      out[p] = out[p - 1];
      --p;
    }
    out[p] = Neighbor{id, label, d};
  }
};

// Nearest, and nearest with a label other than the nearest's (see knn_index.h),
// in (distance, id) order so that the visiting order does not matter.
struct TwoDistinctCollector {
  Neighbor best, second;
  float ratio2 = 0.f;
  float Threshold() const {
    return ratio2 > 0 ? std::min(second.distance, best.distance / ratio2) : second.distance;
  }
  void Offer(float d, std::int32_t id, std::int32_t label) {
    if (ratio2 > 0 && !(d <= best.distance / ratio2) && best.id >= 0) return;
    if (best.id < 0 || Less(d, id, best.distance, best.id)) {
      if (best.id >= 0 && label != best.label) second = best;
      best = Neighbor{id, label, d};
    } else if (label != best.label && (second.id < 0 || Less(d, id, second.distance, second.id))) {
      second = Neighbor{id, label, d};
    }
  }
};

class FfvaIndex final : public KnnIndex {
 public:
  explicit FfvaIndex(const FfvaOptions& o) : options_(o) {
    Require(o.leaf_size >= kBlockLanes && o.leaf_size <= 4096 && o.leaf_size % kBlockLanes == 0,
            ErrorCode::kInvalidArgument, "ffva: leaf_size must be a multiple of 32 in [32, 4096]");
    Require(o.scan_blocks >= 1 && o.scan_blocks <= (1 << 20), ErrorCode::kInvalidArgument,
            "ffva: scan_blocks must be in [1, 2^20]");
  }

  void Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) override;
  void Open(Storage&& storage) { storage_ = std::move(storage); }  // validated by LoadIndex
  // Points the accessors at the sections named by the header (after Build or a validated load).
  void Bind();

  std::size_t size() const override { return n_; }
  int dim() const override { return dim_; }
  std::string name() const override { return approx_ ? "ffva-approx" : "ffva"; }

  void Search(const float* q, int k, Neighbor* out) const override {
    if (k <= 0) return;
    std::fill(out, out + k, Neighbor{});
    internal::RequireFinite(q, 1, dim_, "index: query");
    if (n_ == 0) return;
    KnnCollector c{out, k};
    Run(q, c);
  }

  void SearchTwoDistinct(const float* q, Neighbor out[2], float ratio) const override {
    internal::RequireFinite(q, 1, dim_, "index: query");
    TwoDistinctCollector c;
    c.ratio2 = ratio * ratio;
    if (n_ > 0) Run(q, c);
    out[0] = c.best;
    out[1] = c.second;
  }

  std::uint64_t distance_computations() const override { return computations_.load(); }
  void ResetStats() const override { computations_ = 0; }
  std::size_t memory_bytes() const override { return sizeof(*this) + storage_.size(); }

  const Storage& storage() const { return storage_; }

 private:
  struct Query;
  template <class C>
  void Run(const float* q, C& c) const;
  template <class C>
  void Visit(Query& s, std::int32_t node, double rd, C& c) const;
  template <class C>
  void ScanLeaf(Query& s, const Leaf& leaf, C& c) const;
  template <class C>
  void ScanBlocks(Query& s, std::size_t first_block, std::size_t nblocks, C& c) const;
  template <class C>
  void ScanRange(Query& s, std::size_t first_block, std::size_t nblocks, C& c) const;

  std::int32_t Label(std::size_t pos) const { return labels_ ? labels_[pos] : ids_[pos]; }

  FfvaOptions options_;
  Storage storage_;
  // Views into storage_.
  std::size_t n_ = 0, nblocks_ = 0;
  int dim_ = 0, npairs_ = 0;
  bool approx_ = false;
  const float* cells_ = nullptr;    // dim x 17 cell boundaries
  const float* corners_ = nullptr;  // dim x 16 (approx mode's cell corners)
  const Node* nodes_ = nullptr;
  const Leaf* leaves_ = nullptr;
  const float* boxes_ = nullptr;  // nleaves x (lo[dim], hi[dim])
  const std::uint8_t* codes_ = nullptr;
  // The vectors, in blocks of 32 like the codes; inside a block, 4 groups of 8
  // stored dimension-major ([dim][8]) as the brute-force kernel reads them.
  const float* vectors_ = nullptr;
  const std::int32_t* ids_ = nullptr;
  const std::int32_t* labels_ = nullptr;  // null: labels are ids
  std::uint32_t nnodes_ = 0, nleaves_ = 0;
  std::uint32_t scan_blocks_ = 1;

  const internal::FfvaKernels& k_ = internal::BestFfvaKernels();
  internal::L2Blocks8Fn group_l2_ = internal::BestL2Blocks8();
  mutable std::atomic<std::uint64_t> computations_{0};

  friend std::unique_ptr<KnnIndex> mvkp::LoadIndex(const std::string&, const IndexLoadOptions&);
  friend void mvkp::SaveIndex(const KnnIndex&, const std::string&);
};

// Cell of value v from a dimension's 17 stored boundaries (-inf, 15 edges,
// +inf): the number of edges <= v, so that row[c] <= v < row[c + 1].
inline int CellOfRow(const float* row, float v) {
  int c = 0;
  for (int e = 1; e <= kEdges; ++e) c += v >= row[e];
  return c;
}

// Per-query state: the query, its byte tables and their scale.
struct FfvaIndex::Query {
  const float* q;
  std::vector<float> bound;       // (2*npairs) x 16: per-dimension bound (squared gap, or block distance)
  std::vector<std::uint8_t> lut;  // the same, quantised down to bytes
  float scale_threshold = 0.f;    // threshold the tables were quantised for (0: not yet)
  float inv_scale = 0.f;          // byte units per squared-distance unit
  std::vector<double> offsets;    // kd incremental bound: per-dimension offset of q from the cell
  std::uint32_t masks[4096 / kBlockLanes];
  std::uint8_t sums[4096];
  float dist[kBlockLanes];
  std::uint64_t computed = 0;
  std::size_t done_begin = 0, done_end = 0;  // blocks already searched exhaustively (the first leaf)

  void Quantise(const internal::FfvaKernels& k, float threshold) {
    scale_threshold = threshold;
    // A zero threshold (k exact duplicates found) would make the scale
    // infinite and 0 * inf NaN: the largest finite scale keeps zero bounds
    // at 0 and takes every positive one to 255 instead.
    inv_scale = std::min(kThresholdUnits / threshold, std::numeric_limits<float>::max());
    k.quantise(bound.data(), bound.size(), inv_scale, lut.data());
  }
  // Largest byte sum that may still hold a vector within `threshold`.
  std::uint8_t ByteThreshold(float threshold) const {
    const float t = threshold * inv_scale * (1.f + 1e-5f);  // round the threshold up, never down
    // NaN (an infinite threshold, scale 0) lets everything through, as t >= 255
    // does; converting it to an integer would be undefined.
    return t < 255.f ? std::uint8_t(t) : 255;
  }
};

template <class C>
void FfvaIndex::Run(const float* q, C& c) const {
  thread_local Query s;  // reused buffers; searches on one index may run concurrently
  s.q = q;
  const std::size_t rows = std::size_t(2 * npairs_);
  s.bound.resize(rows * kCells);
  s.lut.resize(rows * kCells);
  s.scale_threshold = 0.f;
  s.computed = 0;
  if (!approx_) {
    k_.gap_tables(cells_, q, dim_, int(rows), kShrink, s.bound.data());
  } else {
    // Thesis block distance: |corner(v) - corner(q)| per dimension.
    std::fill(s.bound.begin(), s.bound.end(), 0.f);
    for (int j = 0; j < dim_; ++j) {
      const float* cr = corners_ + std::size_t(j) * kCells;
      const float cq = cr[CellOfRow(cells_ + std::size_t(j) * kBounds, q[j])];
      for (int cell = 0; cell < kCells; ++cell) s.bound[std::size_t(j) * kCells + cell] = std::fabs(cr[cell] - cq);
    }
  }
  s.offsets.assign(std::size_t(dim_), 0.0);
  s.done_begin = s.done_end = 0;
  Visit(s, 0, 0.0, c);
  computations_.fetch_add(s.computed, std::memory_order_relaxed);
}

// Depth-first, nearer child first, skipping a subtree when the query's
// distance to its cell (kept incrementally, Arya & Mount) exceeds the threshold.
template <class C>
void FfvaIndex::Visit(Query& s, std::int32_t ni, double rd, C& c) const {
  const Node& node = nodes_[ni];
  if (node.nblocks <= scan_blocks_ && c.Threshold() < std::numeric_limits<float>::infinity()) {
    // Small subtree: one filter pass over its blocks beats visiting its leaves.
    ScanBlocks(s, node.first_block, node.nblocks, c);
    return;
  }
  if (node.dim < 0) {
    ScanLeaf(s, leaves_[node.a], c);
    return;
  }
  const double diff = double(s.q[node.dim]) - double(node.split);
  const std::int32_t near = diff <= 0 ? node.a : node.b;
  const std::int32_t far = diff <= 0 ? node.b : node.a;
  Visit(s, near, rd, c);
  double& off = s.offsets[node.dim];
  const double old = off;
  const double frd = rd - old * old + diff * diff;
  if (float(frd) * kShrink > c.Threshold()) return;
  off = diff;
  Visit(s, far, frd, c);
  off = old;
}


template <class C>
void FfvaIndex::ScanLeaf(Query& s, const Leaf& leaf, C& c) const {
  const float* q = s.q;
  const float t = c.Threshold();
  if (t == std::numeric_limits<float>::infinity()) {
    // Nothing to compare with yet (the first leaf): exact distances for the
    // whole leaf, 8 at a time, to set the threshold.
    const std::size_t group_floats = std::size_t(dim_) * kGroup;
    const std::size_t ngroups = (leaf.count + kGroup - 1) / kGroup;
    for (std::size_t g = 0; g < ngroups; ++g) {
      group_l2_(vectors_ + (std::size_t(leaf.first_block) * (kBlockLanes / kGroup) + g) * group_floats, 1, q, dim_,
                s.dist);
      const std::uint32_t lanes = std::uint32_t(std::min<std::size_t>(kGroup, leaf.count - g * kGroup));
      for (std::uint32_t l = 0; l < lanes; ++l) {
        const std::size_t pos = leaf.first + g * kGroup + l;
        c.Offer(s.dist[l], ids_[pos], Label(pos));
      }
      s.computed += lanes;
    }
    if (s.done_end == s.done_begin) {
      s.done_begin = leaf.first_block;
      s.done_end = leaf.first_block + (leaf.count + kBlockLanes - 1) / kBlockLanes;
    }
    return;
  }
  // Tight bounding box of the leaf's vectors.
  const float* box = boxes_ + std::size_t(&leaf - leaves_) * 2 * dim_;
  if (k_.box(box, box + dim_, q, dim_) * kShrink > t) return;
  ScanRange(s, leaf.first_block, (leaf.count + kBlockLanes - 1) / kBlockLanes, c);
}

// Filter then refine blocks [first, first + nblocks), minus the first leaf's.
template <class C>
void FfvaIndex::ScanBlocks(Query& s, std::size_t first, std::size_t nblocks, C& c) const {
  const std::size_t end = first + nblocks;
  if (s.done_end <= first || s.done_begin >= end || s.done_begin == s.done_end) {
    ScanRange(s, first, nblocks, c);
    return;
  }
  if (first < s.done_begin) ScanRange(s, first, s.done_begin - first, c);
  if (s.done_end < end) ScanRange(s, s.done_end, end - s.done_end, c);
}

// Vectors are stored in block order with 32 per block (only the very last
// block may be partial), so lane l of block b is vector b * 32 + l.
template <class C>
void FfvaIndex::ScanRange(Query& s, std::size_t first, std::size_t nblocks, C& c) const {
  const float* q = s.q;
  float t = c.Threshold();
  const std::size_t group_floats = std::size_t(dim_) * kGroup;
  constexpr std::size_t kChunk = sizeof(s.masks) / sizeof(s.masks[0]);
  for (std::size_t b0 = first; b0 < first + nblocks; b0 += kChunk) {
    const std::size_t cb = std::min(kChunk, first + nblocks - b0);
    // (Re-)quantise the tables when the threshold has shrunk enough to lose resolution.
    if (s.scale_threshold == 0.f || t < 0.25f * s.scale_threshold) s.Quantise(k_, t);
    std::uint8_t thr = s.ByteThreshold(t);
    k_.scan(codes_ + b0 * npairs_ * kBlockLanes, cb, npairs_, s.lut.data(), thr, s.sums, s.masks);
    if (b0 + cb == nblocks_ && n_ % kBlockLanes) s.masks[cb - 1] &= (1u << (n_ % kBlockLanes)) - 1;
    for (std::size_t b = 0; b < cb; ++b) {
      const std::uint32_t m = s.masks[b];
      if (!m) continue;
      for (int g = 0; g < kBlockLanes / kGroup; ++g) {
        std::uint32_t gm = (m >> (g * kGroup)) & 0xFFu;
        // Lanes whose bound still passes (the threshold may have shrunk since the scan).
        for (std::uint32_t x = gm; x; x &= x - 1) {
          const int l = __builtin_ctz(x);
          if (s.sums[b * kBlockLanes + std::size_t(g * kGroup + l)] > thr) gm &= ~(1u << l);
        }
        if (!gm) continue;
        const std::size_t block = b0 + b;
        group_l2_(vectors_ + (block * (kBlockLanes / kGroup) + std::size_t(g)) * group_floats, 1, q, dim_, s.dist);
        for (std::uint32_t x = gm; x; x &= x - 1) {
          const int l = __builtin_ctz(x);
          const std::size_t pos = block * kBlockLanes + std::size_t(g * kGroup + l);
          ++s.computed;
          c.Offer(s.dist[l], ids_[pos], Label(pos));
        }
        const float nt = c.Threshold();
        if (nt < t) {
          t = nt;
          thr = s.ByteThreshold(t);
        }
      }
    }
  }
}

// ---- building --------------------------------------------------------------

struct Layout {
  std::size_t cells, corners, nodes, leaves, boxes, codes, vectors, ids, labels, total;
};

Layout MakeLayout(std::size_t n, int dim, int npairs, std::size_t nblocks, std::size_t nnodes, std::size_t nleaves,
                  bool has_labels) {
  Layout l{};
  std::size_t at = kHeaderBytes;
  auto take = [&](std::size_t bytes) {
    const std::size_t off = at;
    at = AlignUp(at + bytes);
    return off;
  };
  l.cells = take(std::size_t(dim) * kBounds * sizeof(float));
  l.corners = take(std::size_t(dim) * kCells * sizeof(float));
  l.nodes = take(nnodes * sizeof(Node));
  l.leaves = take(nleaves * sizeof(Leaf));
  l.boxes = take(nleaves * 2 * std::size_t(dim) * sizeof(float));
  l.codes = take(nblocks * std::size_t(npairs) * kBlockLanes);
  l.vectors = take(nblocks * kBlockLanes * std::size_t(dim) * sizeof(float));
  l.ids = take(n * sizeof(std::int32_t));
  l.labels = take(has_labels ? n * sizeof(std::int32_t) : 0);
  l.total = at;
  return l;
}

struct TreeBuilder {
  const float* data;
  int dim;
  int leaf_size;
  std::vector<std::uint32_t> perm;
  std::vector<Node> nodes;
  std::vector<Leaf> leaves;
  std::uint32_t blocks = 0;

  // Builds the subtree over perm[begin, end); returns its node index.
  std::int32_t Make(std::size_t begin, std::size_t end, int depth) {
    const std::size_t count = end - begin;
    const std::int32_t me = std::int32_t(nodes.size());
    nodes.push_back({-1, 0.f, 0, 0, blocks, 0});
    int best_dim = -1;
    if (count > std::size_t(leaf_size) && depth < kMaxDepth - 1) {
      // Widest dimension by variance, on at most 4096 evenly spaced members.
      const std::size_t step = std::max<std::size_t>(1, count / 4096);
      double best = 0.0;
      for (int j = 0; j < dim; ++j) {
        double s = 0, s2 = 0, m = 0;
        for (std::size_t i = begin; i < end; i += step) {
          const double v = data[std::size_t(perm[i]) * dim + j];
          s += v;
          s2 += v * v;
          m += 1;
        }
        const double var = s2 / m - (s / m) * (s / m);
        if (var > best) {
          best = var;
          best_dim = j;
        }
      }
    }
    if (best_dim < 0) {  // small enough, or all points equal
      nodes[me].a = std::int32_t(leaves.size());
      leaves.push_back({std::uint32_t(begin), std::uint32_t(count), blocks, 0});
      blocks += std::uint32_t((count + kBlockLanes - 1) / kBlockLanes);
      nodes[me].nblocks = blocks - nodes[me].first_block;
      return me;
    }
    // Left part: whole blocks, about half, so only the last leaf of the whole
    // tree can end in a partial block.
    const std::size_t nb = (count + kBlockLanes - 1) / kBlockLanes;
    const std::size_t left = kBlockLanes * (nb / 2);
    auto key = [&](std::uint32_t i) { return data[std::size_t(i) * dim + best_dim]; };
    std::nth_element(perm.begin() + std::ptrdiff_t(begin), perm.begin() + std::ptrdiff_t(begin + left),
                     perm.begin() + std::ptrdiff_t(end), [&](std::uint32_t x, std::uint32_t y) {
                       const float kx = key(x), ky = key(y);
                       return kx < ky || (kx == ky && x < y);
                     });
    const float split = key(perm[begin + left]);
    nodes[me].dim = best_dim;
    nodes[me].split = split;
    const std::int32_t a = Make(begin, begin + left, depth + 1);
    const std::int32_t b = Make(begin + left, end, depth + 1);
    nodes[me].a = a;
    nodes[me].b = b;
    nodes[me].nblocks = blocks - nodes[me].first_block;
    return me;
  }
};

void FfvaIndex::Build(const float* data, std::size_t n, int dim, const std::int32_t* labels) {
  Require(dim >= 1 && dim <= 65536, ErrorCode::kInvalidArgument, "ffva: dimension must be in [1, 65536]");
  Require(n < (std::size_t(1) << 31), ErrorCode::kInvalidArgument, "ffva: at most 2^31 - 1 vectors");
  internal::RequireFinite(data, n, dim, "index: database");
  const int npairs = (dim + 1) / 2;

  // Cell boundaries per dimension: equal-count partition of (a sample of) the data.
  std::vector<float> cells(std::size_t(dim) * kBounds, 0.f), corners(std::size_t(dim) * kCells, 0.f);
  {
    const std::size_t step = std::max<std::size_t>(1, n / 65536);
    std::vector<float> v;
    for (int j = 0; j < dim; ++j) {
      v.clear();
      for (std::size_t i = 0; i < n; i += step) v.push_back(data[i * dim + j]);
      std::sort(v.begin(), v.end());
      float* row = cells.data() + std::size_t(j) * kBounds;
      float* e = row + 1;
      float* cr = corners.data() + std::size_t(j) * kCells;
      row[0] = -std::numeric_limits<float>::infinity();
      row[kBounds - 1] = std::numeric_limits<float>::infinity();
      for (int c = 0; c < kEdges; ++c) e[c] = v.empty() ? 0.f : v[(std::size_t(c) + 1) * v.size() / kCells];
      cr[0] = v.empty() ? 0.f : v.front();
      for (int c = 1; c < kCells; ++c) cr[c] = e[c - 1];
    }
  }

  TreeBuilder tb{data, dim, options_.leaf_size, {}, {}, {}, 0};
  tb.perm.resize(n);
  std::iota(tb.perm.begin(), tb.perm.end(), 0u);
  if (n > 0) tb.Make(0, n, 0);

  const bool has_labels = labels != nullptr;
  const Layout L = MakeLayout(n, dim, npairs, tb.blocks, tb.nodes.size(), tb.leaves.size(), has_labels);
  Storage st;
  st.Allocate(L.total);
  std::uint8_t* base = st.mutable_data();
  Header h{};
  std::memcpy(h.magic, kMagic, 8);
  h.version = kFormatVersion;
  h.header_bytes = kHeaderBytes;
  h.file_bytes = L.total;
  h.n = n;
  h.nblocks = tb.blocks;
  h.dim = std::uint32_t(dim);
  h.npairs = std::uint32_t(npairs);
  h.nnodes = std::uint32_t(tb.nodes.size());
  h.nleaves = std::uint32_t(tb.leaves.size());
  h.leaf_size = std::uint32_t(options_.leaf_size);
  h.reserved = std::uint32_t(options_.scan_blocks);
  h.filter = options_.filter == FfvaOptions::Filter::kApprox ? 1 : 0;
  h.has_labels = has_labels;
  h.off_cells = L.cells;
  h.off_corners = L.corners;
  h.off_nodes = L.nodes;
  h.off_leaves = L.leaves;
  h.off_boxes = L.boxes;
  h.off_codes = L.codes;
  h.off_vectors = L.vectors;
  h.off_ids = L.ids;
  h.off_labels = L.labels;
  std::memcpy(base + L.cells, cells.data(), cells.size() * sizeof(float));
  std::memcpy(base + L.corners, corners.data(), corners.size() * sizeof(float));
  if (!tb.nodes.empty()) std::memcpy(base + L.nodes, tb.nodes.data(), tb.nodes.size() * sizeof(Node));
  if (!tb.leaves.empty()) std::memcpy(base + L.leaves, tb.leaves.data(), tb.leaves.size() * sizeof(Leaf));
  auto* vec = reinterpret_cast<float*>(base + L.vectors);
  auto* ids = reinterpret_cast<std::int32_t*>(base + L.ids);
  auto* labs = reinterpret_cast<std::int32_t*>(base + L.labels);
  for (std::size_t pos = 0; pos < n; ++pos) {
    const std::size_t i = tb.perm[pos];
    ids[pos] = std::int32_t(i);
    if (has_labels) labs[pos] = labels[i];
  }
  auto* boxes = reinterpret_cast<float*>(base + L.boxes);
  auto* codes = base + L.codes;
  for (std::size_t li = 0; li < tb.leaves.size(); ++li) {
    const Leaf& leaf = tb.leaves[li];
    float* lo = boxes + li * 2 * dim;
    float* hi = lo + dim;
    std::fill(lo, lo + dim, std::numeric_limits<float>::infinity());
    std::fill(hi, hi + dim, -std::numeric_limits<float>::infinity());
    for (std::uint32_t r = 0; r < leaf.count; ++r) {
      const std::size_t pos = leaf.first + r;
      const float* x = data + std::size_t(tb.perm[pos]) * dim;
      const std::size_t block = std::size_t(leaf.first_block) + r / kBlockLanes;
      std::uint8_t* blk = codes + block * npairs * kBlockLanes;
      const int lane = int(r % kBlockLanes);
      float* group = vec + (block * (kBlockLanes / kGroup) + std::size_t(lane / kGroup)) * dim * kGroup;
      for (int j = 0; j < dim; ++j) {
        group[j * kGroup + lane % kGroup] = x[j];
        lo[j] = std::min(lo[j], x[j]);
        hi[j] = std::max(hi[j], x[j]);
        const int c = CellOfRow(cells.data() + std::size_t(j) * kBounds, x[j]);
        blk[(j / 2) * kBlockLanes + lane] |= std::uint8_t(j % 2 ? c << 4 : c);
      }
    }
  }
  h.payload_crc = Crc32(base + kHeaderBytes, L.total - kHeaderBytes);
  h.header_crc = Crc32(&h, offsetof(Header, header_crc));
  std::memcpy(base, &h, sizeof(h));
  storage_ = std::move(st);
  Bind();
}

void FfvaIndex::Bind() {
  Header h;
  std::memcpy(&h, storage_.data(), sizeof(h));
  const std::uint8_t* base = storage_.data();
  n_ = h.n;
  nblocks_ = h.nblocks;
  dim_ = int(h.dim);
  npairs_ = int(h.npairs);
  nnodes_ = h.nnodes;
  nleaves_ = h.nleaves;
  approx_ = h.filter == 1;
  options_.leaf_size = int(h.leaf_size);
  options_.scan_blocks = int(h.reserved);
  scan_blocks_ = h.reserved;
  options_.filter = approx_ ? FfvaOptions::Filter::kApprox : FfvaOptions::Filter::kExact;
  cells_ = reinterpret_cast<const float*>(base + h.off_cells);
  corners_ = reinterpret_cast<const float*>(base + h.off_corners);
  nodes_ = reinterpret_cast<const Node*>(base + h.off_nodes);
  leaves_ = reinterpret_cast<const Leaf*>(base + h.off_leaves);
  boxes_ = reinterpret_cast<const float*>(base + h.off_boxes);
  codes_ = base + h.off_codes;
  vectors_ = reinterpret_cast<const float*>(base + h.off_vectors);
  ids_ = reinterpret_cast<const std::int32_t*>(base + h.off_ids);
  labels_ = h.has_labels ? reinterpret_cast<const std::int32_t*>(base + h.off_labels) : nullptr;
}

// ---- loading ---------------------------------------------------------------

// Checks everything Bind() and the search rely on, so that no file can make
// the search read out of bounds or loop.
void Validate(const std::uint8_t* base, std::size_t size, const std::string& name, bool verify_checksum) {
  if (size < 8 || std::memcmp(base, kMagic, 8) != 0) BadIndex(name, "not an mvkp index file (bad magic)");
  if (size < kHeaderBytes) BadIndex(name, "truncated index file (" + std::to_string(size) + " bytes)");
  Header h;
  std::memcpy(&h, base, sizeof(h));
  if (h.version > kFormatVersion)
    BadIndex(name, "index format version " + std::to_string(h.version) + " is newer than this mvkp reads (" +
                       std::to_string(kFormatVersion) + ")");
  if (h.version != kFormatVersion) BadIndex(name, "unknown index format version " + std::to_string(h.version));
  if (Crc32(&h, offsetof(Header, header_crc)) != h.header_crc) BadIndex(name, "corrupt index header (checksum mismatch)");
  if (h.header_bytes != kHeaderBytes) BadIndex(name, "corrupt index header (header size)");
  if (h.file_bytes != size)
    BadIndex(name, size < h.file_bytes ? "truncated index file (" + std::to_string(size) + " of " +
                                             std::to_string(h.file_bytes) + " bytes)"
                                       : "index file has trailing bytes");
  if (h.dim < 1 || h.dim > 65536 || h.npairs != (h.dim + 1) / 2) BadIndex(name, "corrupt index (dimension)");
  if (h.n >= (std::uint64_t(1) << 31) || h.filter > 1 || h.has_labels > 1) BadIndex(name, "corrupt index (counts)");
  if (h.leaf_size < 32 || h.leaf_size > 4096 || h.leaf_size % 32) BadIndex(name, "corrupt index (leaf size)");
  if (h.reserved < 1 || h.reserved > (1u << 20)) BadIndex(name, "corrupt index (scan blocks)");
  if ((h.n == 0) != (h.nnodes == 0) || h.nleaves > h.nnodes || h.nblocks > h.n + h.nleaves)
    BadIndex(name, "corrupt index (tree size)");
  const Layout L = MakeLayout(h.n, int(h.dim), int(h.npairs), h.nblocks, h.nnodes, h.nleaves, h.has_labels);
  if (L.total != h.file_bytes || L.cells != h.off_cells || L.corners != h.off_corners || L.nodes != h.off_nodes ||
      L.leaves != h.off_leaves || L.boxes != h.off_boxes || L.codes != h.off_codes || L.vectors != h.off_vectors ||
      L.ids != h.off_ids || L.labels != h.off_labels)
    BadIndex(name, "corrupt index (section layout)");
  if (verify_checksum && Crc32(base + kHeaderBytes, size - kHeaderBytes) != h.payload_crc)
    BadIndex(name, "corrupt index (checksum mismatch)");

  // Structure, checked even without the checksum.
  const auto* cells = reinterpret_cast<const float*>(base + h.off_cells);
  for (std::size_t j = 0; j < h.dim; ++j) {
    const float* row = cells + j * kBounds;
    bool ok = row[0] == -std::numeric_limits<float>::infinity() &&
              row[kBounds - 1] == std::numeric_limits<float>::infinity();
    for (int c = 1; c < kBounds - 1; ++c) ok = ok && std::isfinite(row[c]) && (c == 1 || row[c] >= row[c - 1]);
    if (!ok) BadIndex(name, "corrupt index (cell boundaries)");
  }
  const auto* nodes = reinterpret_cast<const Node*>(base + h.off_nodes);
  const auto* leaves = reinterpret_cast<const Leaf*>(base + h.off_leaves);
  // Preorder with children after parents: no cycles; depth bounded; every leaf once.
  std::vector<std::uint8_t> depth(h.nnodes, 0);
  std::vector<std::uint8_t> leaf_seen(h.nleaves, 0);
  std::vector<std::uint8_t> reached(h.nnodes, 0);
  if (h.nnodes) reached[0] = 1;
  for (std::uint32_t i = 0; i < h.nnodes; ++i) {
    const Node& nd = nodes[i];
    if (!reached[i]) BadIndex(name, "corrupt index (unreachable tree node)");
    if (nd.dim < 0) {
      if (nd.dim != -1 || nd.a < 0 || std::uint32_t(nd.a) >= h.nleaves || leaf_seen[nd.a]++)
        BadIndex(name, "corrupt index (tree leaf)");
      continue;
    }
    if (std::uint32_t(nd.dim) >= h.dim || !std::isfinite(nd.split) || nd.a <= std::int32_t(i) ||
        nd.b <= std::int32_t(i) || std::uint32_t(nd.a) >= h.nnodes || std::uint32_t(nd.b) >= h.nnodes ||
        nd.a == nd.b || reached[nd.a] || reached[nd.b] || depth[i] + 1 >= kMaxDepth)
      BadIndex(name, "corrupt index (tree node)");
    reached[nd.a] = reached[nd.b] = 1;
    depth[nd.a] = depth[nd.b] = std::uint8_t(depth[i] + 1);
  }
  std::uint64_t next = 0, next_block = 0;
  for (std::uint32_t i = 0; i < h.nleaves; ++i) {
    const Leaf& lf = leaves[i];
    if (!leaf_seen[i] || lf.count == 0 || lf.first != next || lf.first_block != next_block)
      BadIndex(name, "corrupt index (leaf ranges)");
    next += lf.count;
    next_block += (lf.count + kBlockLanes - 1) / kBlockLanes;
  }
  if (next != h.n || next_block != h.nblocks) BadIndex(name, "corrupt index (leaf ranges)");
  // Only the last leaf may end in a partial block (ScanRange relies on it).
  for (std::uint32_t i = 0; i + 1 < h.nleaves; ++i)
    if (leaves[i].count % kBlockLanes) BadIndex(name, "corrupt index (leaf ranges)");
  // Subtree block ranges, children first.
  for (std::uint32_t i = h.nnodes; i-- > 0;) {
    const Node& nd = nodes[i];
    bool ok;
    if (nd.dim < 0) {
      const Leaf& lf = leaves[nd.a];
      ok = nd.first_block == lf.first_block && nd.nblocks == (lf.count + kBlockLanes - 1) / kBlockLanes;
    } else {
      const Node& a = nodes[nd.a];
      const Node& b = nodes[nd.b];
      ok = a.first_block == nd.first_block && b.first_block == std::uint64_t(a.first_block) + a.nblocks &&
           std::uint64_t(nd.nblocks) == std::uint64_t(a.nblocks) + b.nblocks;
    }
    if (!ok) BadIndex(name, "corrupt index (subtree ranges)");
  }
  if (h.nnodes && (nodes[0].first_block != 0 || nodes[0].nblocks != h.nblocks))
    BadIndex(name, "corrupt index (subtree ranges)");
  const auto* ids = reinterpret_cast<const std::int32_t*>(base + h.off_ids);
  std::vector<bool> seen(h.n, false);
  for (std::uint64_t i = 0; i < h.n; ++i) {
    if (ids[i] < 0 || std::uint64_t(ids[i]) >= h.n || seen[ids[i]]) BadIndex(name, "corrupt index (vector ids)");
    seen[ids[i]] = true;
  }
  if (verify_checksum) {
    const auto* vec = reinterpret_cast<const float*>(base + h.off_vectors);
    try {
      internal::RequireFinite(vec, h.nblocks * kBlockLanes, int(h.dim), "vectors");
    } catch (const Error&) {
      BadIndex(name, "corrupt index (non-finite vector)");
    }
  }
}

}  // namespace

std::unique_ptr<KnnIndex> MakeFfvaIndex(const FfvaOptions& options) { return std::make_unique<FfvaIndex>(options); }

void SaveIndex(const KnnIndex& index, const std::string& path) {
  const auto* f = dynamic_cast<const FfvaIndex*>(&index);
  Require(f != nullptr, ErrorCode::kInvalidArgument,
          "only FFVA indexes (modes exact and approx) can be saved, not '" + index.name() + "'");
  Require(f->storage().size() >= kHeaderBytes, ErrorCode::kInvalidArgument, "cannot save an index that was never built");
  WriteFileAtomically(path, f->storage().data(), f->storage().size());
}

std::unique_ptr<KnnIndex> LoadIndex(const std::string& path, const IndexLoadOptions& options) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(ErrorCode::kIo, path + ": cannot open index (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Error(ErrorCode::kIo, path + ": not a regular file");
  }
  const std::size_t size = std::size_t(st.st_size);
  if (size < kHeaderBytes) {
    ::close(fd);
    BadIndex(path, size >= 8 ? "truncated index file (" + std::to_string(size) + " bytes)"
                             : "not an mvkp index file (too short)");
  }
  Storage storage;
  if (options.mmap) {
    void* p = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
    ::close(fd);
    if (p == MAP_FAILED) throw Error(ErrorCode::kIo, path + ": cannot map index (" + std::strerror(errno) + ")");
    storage.Map(p, size);
  } else {
    storage.Allocate(size);
    std::size_t got = 0;
    while (got < size) {
      const ssize_t r = ::read(fd, storage.mutable_data() + got, size - got);
      if (r <= 0) {
        ::close(fd);
        throw Error(ErrorCode::kIo, path + ": read failed");
      }
      got += std::size_t(r);
    }
    ::close(fd);
  }
  Validate(storage.data(), size, path, options.verify_checksum);
  auto index = std::make_unique<FfvaIndex>(FfvaOptions{});
  index->Open(std::move(storage));
  index->Bind();
  return index;
}

std::unique_ptr<KnnIndex> MakeIndexByName(const std::string& mode) {
  if (mode == "brute") return MakeBruteForceIndex();
  if (mode == "exact") return MakeFfvaIndex();
  if (mode == "approx") {
    FfvaOptions o;
    o.filter = FfvaOptions::Filter::kApprox;
    return MakeFfvaIndex(o);
  }
  throw Error(ErrorCode::kInvalidArgument, "unknown index mode '" + mode + "' (expected exact, approx or brute)");
}

}  // namespace mvkp
