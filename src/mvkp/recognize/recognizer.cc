#include "mvkp/recognize/recognizer.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <unordered_map>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/ivf.h"

namespace mvkp {

void RecognizerOptions::Check() const {
  match.Check();
  Require(max_locations >= 4 && max_locations <= 256, ErrorCode::kInvalidArgument, "max locations must be in 4..256");
  Require(words_per_location >= 1 && words_per_location <= 64, ErrorCode::kInvalidArgument,
          "words per location must be in 1..64");
  Require(query_words >= 1 && query_words <= 8, ErrorCode::kInvalidArgument, "query words must be in 1..8");
  Require(max_hamming >= 0 && max_hamming <= 32, ErrorCode::kInvalidArgument, "max hamming must be in 0..32");
  Require(probe_words >= 0 && probe_words <= 65536, ErrorCode::kInvalidArgument, "probe words must be in 0..65536");
  Require(max_candidates >= 1 && max_candidates <= 100000, ErrorCode::kInvalidArgument,
          "max candidates must be in 1..100000");
  Require(min_votes >= 4, ErrorCode::kInvalidArgument, "min votes must be >= 4");
  Require(min_inliers >= 4, ErrorCode::kInvalidArgument, "min inliers must be >= 4");
}

namespace {

// Name of the first query-side feature setting that differs, or "".
std::string FeatureMismatch(const ModelParams& a, const ModelParams& b) {
  if (a.smooth_sigma != b.smooth_sigma) return "smooth_sigma";
  if (a.patch_size != b.patch_size) return "patch_size";
  if (a.dims != b.dims) return "dims";
  if (a.orient != b.orient) return "orient";
  if (a.orientation_radius != b.orientation_radius) return "orientation_radius";
  if (a.min_strength != b.min_strength) return "min_strength";
  if (a.relative_threshold != b.relative_threshold) return "relative_threshold";
  if (a.min_distance != b.min_distance) return "min_distance";
  if (a.block_size != b.block_size) return "block_size";
  return "";
}

// Object locations are stored in quarter pixels: 4 bytes per location.
constexpr float kLocationScale = 4.f;
constexpr float kMaxObjectSide = 65535.f / kLocationScale;

// One stored (target, location, signature) in a word's list: 6 bytes, the
// 20-bit signature, the 8-bit location and the 20-bit target slot packed
// (at most 2^20 targets). Signatures keep the first 20 dimensions' bits.
constexpr std::uint32_t kSignatureMask = (1u << 20) - 1;
constexpr std::size_t kMaxSlots = std::size_t(1) << 20;
struct __attribute__((packed)) Posting {
  std::uint32_t lo;  // signature | location << 20 | (slot & 15) << 28
  std::uint16_t hi;  // slot >> 4
  static Posting Make(std::uint32_t slot, std::uint32_t loc, std::uint32_t signature) {
    return {(signature & kSignatureMask) | loc << 20 | (slot & 15u) << 28, std::uint16_t(slot >> 4)};
  }
  std::uint32_t signature() const { return lo & kSignatureMask; }
  std::uint32_t location() const { return (lo >> 20) & 0xffu; }
  std::uint32_t slot() const { return lo >> 28 | std::uint32_t(hi) << 4; }
};
static_assert(sizeof(Posting) == 6);

// A target as kWords stores it, independent of its slot: what Encode
// serialises and AddEncoded reads back.
struct Encoded {
  ModelParams params;  // the query-side feature settings
  int width = 0, height = 0;
  std::vector<std::uint16_t> xy;  // 2 per kept location, quarter pixels
  struct Entry {
    std::int32_t word;
    std::uint32_t location;
    std::uint32_t signature;
  };
  std::vector<Entry> entries;
};

struct Vote {
  cv::Point2f object, query;
  int query_index;
  float ratio = 0;  // kExact: d1 / d2 (PROSAC tries the lowest first)
};

// At most `max` locations of m: the top level's first (the target at full
// size, which most frames show), then the smaller levels' in proportion to
// their counts; each level's best ranked first. Giving the smaller levels a
// fixed share (20 %) lost views of full-size targets in the recognizer tests,
// so with 150 kept locations a 320-px target keeps its top level only.
std::vector<int> KeptLocations(const Model& m, int max) {
  const int n = int(m.locations.size());
  std::vector<std::vector<int>> by_level(std::size_t(std::max(1, m.params.levels)));
  for (int l = 0; l < n; ++l)
    by_level[std::size_t(std::clamp(m.locations[std::size_t(l)].level, 0, int(by_level.size()) - 1))].push_back(l);
  std::vector<int> quota(by_level.size(), 0);
  int rest_total = 0;
  for (std::size_t k = 1; k < by_level.size(); ++k) rest_total += int(by_level[k].size());
  quota[0] = std::min(int(by_level[0].size()), max);
  int left = std::min(max - quota[0], rest_total);
  for (std::size_t k = 1; k < by_level.size() && rest_total > 0; ++k)
    quota[k] = int(std::floor(double(left) * double(by_level[k].size()) / rest_total));
  int given = 0;
  for (int q : quota) given += q;
  // Whatever is left (rounding, or a short level) goes to the levels in order.
  for (std::size_t k = 0; given < std::min(max, n) && k < by_level.size(); ++k) {
    const int extra = std::min(int(by_level[k].size()) - quota[k], std::min(max, n) - given);
    quota[k] += extra;
    given += extra;
  }
  std::vector<int> out;
  for (std::size_t k = 0; k < by_level.size(); ++k)
    for (int i = 0; i < quota[k]; ++i) out.push_back(by_level[k][std::size_t(i)]);
  return out;
}
}  // namespace

struct Recognizer::Impl {
  struct Target {
    std::string id;
    int width = 0, height = 0;
    std::vector<std::uint16_t> xy;        // kWords: 2 per kept location, quarter pixels
    std::shared_ptr<const Model> model;   // kExact or keep_models
    mutable std::vector<std::int32_t> cells;  // kExact with probe_words: each centre's nearest word (cached)
    bool alive = false;
    cv::Point2f location(int loc) const {
      return {xy[2 * std::size_t(loc)] / kLocationScale, xy[2 * std::size_t(loc) + 1] / kLocationScale};
    }
  };

  const Vocabulary* vocab = nullptr;
  bool have_params = false;
  ModelParams params;
  std::string first_id;
  std::vector<Target> slots;
  std::vector<std::uint32_t> free_slots;
  std::unordered_map<std::string, std::uint32_t> by_id;
  std::vector<std::vector<Posting>> lists;  // kWords: one per word

  // kExact: built lazily from the alive slots.
  mutable std::mutex mutex;
  mutable std::unique_ptr<KnnIndex> index;
  mutable bool dirty = true;
  mutable std::vector<std::uint32_t> label_slot;    // global location id -> slot
  mutable std::vector<std::int32_t> row_offset;     // slot -> its first row in the index
  mutable std::map<std::string, std::shared_ptr<const Matcher>> focus;  // RecognizeOne's matchers

  void EnsureIndex(const RecognizerOptions& o) const;
  Encoded Encode(const Model& m, const RecognizerOptions& o) const;
  // Throw Error(kInvalidArgument) for an empty or taken id, and for query-side
  // feature settings that differ from the targets already held.
  void RequireNewId(const std::string& id) const {
    Require(!id.empty(), ErrorCode::kInvalidArgument, "target id must not be empty");
    Require(!by_id.count(id), ErrorCode::kInvalidArgument, "target '" + id + "' already exists");
  }
  void RequireSameFeatures(const std::string& id, const ModelParams& p) const {
    if (!have_params) return;
    const std::string diff = FeatureMismatch(params, p);
    Require(diff.empty(), ErrorCode::kInvalidArgument,
            "target '" + id + "': feature setting " + diff + " differs from the targets already added (e.g. '" +
                first_id + "'); all targets must share the query-side feature settings");
  }
  // Takes a slot and stores the target (all checks done before).
  void Insert(const std::string& id, Encoded e, std::shared_ptr<const Model> model);
};

Encoded Recognizer::Impl::Encode(const Model& m, const RecognizerOptions& o) const {
  Encoded enc;
  enc.params = m.params;
  enc.width = m.object_width;
  enc.height = m.object_height;
  // The kept locations: the most stable of each pyramid level in proportion
  // to the level's share of the model (levels are stored largest first, each
  // ranked), so a target keeps its small-scale levels too.
  const std::vector<int> kept = KeptLocations(m, o.max_locations);
  const int L = int(kept.size());
  std::vector<int> kept_index(m.locations.size(), -1);
  for (int k = 0; k < L; ++k) kept_index[std::size_t(kept[std::size_t(k)])] = k;
  auto& xy = enc.xy;
  xy.resize(2 * std::size_t(L));
  for (int l = 0; l < L; ++l) {
    const auto& p = m.locations[std::size_t(kept[std::size_t(l)])];
    xy[2 * std::size_t(l)] = std::uint16_t(std::lround(std::clamp(p.x, 0.f, kMaxObjectSide) * kLocationScale));
    xy[2 * std::size_t(l) + 1] = std::uint16_t(std::lround(std::clamp(p.y, 0.f, kMaxObjectSide) * kLocationScale));
  }
  // The centres of the kept locations, quantised.
  std::vector<int> rows;
  for (int r = 0; r < m.descriptors.rows; ++r)
    if (kept_index[std::size_t(m.labels[std::size_t(r)])] >= 0) rows.push_back(r);
  const int dims = m.descriptors.cols;
  std::vector<float> x(rows.size() * std::size_t(dims));
  for (std::size_t i = 0; i < rows.size(); ++i)
    std::copy_n(m.descriptors.ptr<float>(rows[i]), dims, &x[i * std::size_t(dims)]);
  std::vector<WordAssignment> wa(rows.size());
  vocab->Quantize(x.data(), rows.size(), 1, wa.data());

  // Per location: the words its centres fall in most often (ties: nearer
  // centres first), each with the signature of the mean of those centres.
  struct WordStat {
    int word = 0, count = 0;
    float distance = 0;
    std::vector<double> sum;
  };
  std::vector<std::vector<WordStat>> per_loc(static_cast<std::size_t>(L));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    auto& ws = per_loc[std::size_t(kept_index[std::size_t(m.labels[std::size_t(rows[i])])])];
    auto it = std::find_if(ws.begin(), ws.end(), [&](const WordStat& s) { return s.word == wa[i].word; });
    if (it == ws.end()) {
      ws.push_back({wa[i].word, 0, 0.f, std::vector<double>(std::size_t(dims), 0.0)});
      it = ws.end() - 1;
    }
    ++it->count;
    it->distance += wa[i].distance;
    for (int j = 0; j < dims; ++j) it->sum[std::size_t(j)] += x[i * std::size_t(dims) + std::size_t(j)];
  }
  std::vector<float> mean(static_cast<std::size_t>(dims));
  for (int l = 0; l < L; ++l) {
    auto& ws = per_loc[std::size_t(l)];
    std::stable_sort(ws.begin(), ws.end(), [](const WordStat& a, const WordStat& b) {
      return a.count != b.count ? a.count > b.count : a.distance / float(a.count) < b.distance / float(b.count);
    });
    for (std::size_t k = 0; k < ws.size() && int(k) < o.words_per_location; ++k) {
      for (int j = 0; j < dims; ++j) mean[std::size_t(j)] = float(ws[k].sum[std::size_t(j)] / ws[k].count);
      enc.entries.push_back({ws[k].word, std::uint32_t(l), vocab->Signature(mean.data(), ws[k].word)});
    }
  }
  return enc;
}

void Recognizer::Impl::Insert(const std::string& id, Encoded e, std::shared_ptr<const Model> model) {
  std::uint32_t slot;
  if (!free_slots.empty()) {
    slot = free_slots.back();
  } else {
    Require(slots.size() < kMaxSlots, ErrorCode::kInvalidArgument, "too many targets (1048576)");
    slot = std::uint32_t(slots.size());
  }
  Target t;
  t.id = id;
  t.width = e.width;
  t.height = e.height;
  t.alive = true;
  t.xy = std::move(e.xy);
  t.model = std::move(model);
  if (slot == slots.size()) slots.emplace_back();
  else free_slots.pop_back();
  slots[slot] = std::move(t);
  for (const auto& x : e.entries) lists[std::size_t(x.word)].push_back(Posting::Make(slot, x.location, x.signature));
  by_id.emplace(id, slot);
  if (!have_params) {
    have_params = true;
    params = e.params;
    first_id = id;
  }
  dirty = true;
}

void Recognizer::Impl::EnsureIndex(const RecognizerOptions& o) const {
  std::lock_guard<std::mutex> lock(mutex);
  if (!dirty) return;
  index.reset();
  label_slot.clear();
  row_offset.assign(slots.size(), 0);
  std::vector<float> data;
  std::vector<std::int32_t> labels;
  std::int64_t rows = 0;
  for (std::uint32_t s = 0; s < slots.size(); ++s) {
    if (!slots[s].alive) continue;
    const Model& m = *slots[s].model;
    const std::int64_t offset = std::int64_t(label_slot.size());
    Require(offset + std::int64_t(m.locations.size()) < std::numeric_limits<std::int32_t>::max() &&
                rows + m.descriptors.rows < std::numeric_limits<std::int32_t>::max(),
            ErrorCode::kInvalidArgument, "too many object locations over all targets");
    // Labels are places (a point seen at two pyramid levels is one place),
    // so the second neighbour is another place; the row gives the location.
    const std::vector<std::int32_t> place = LocationPlaces(m);
    row_offset[s] = std::int32_t(rows);
    for (int r = 0; r < m.descriptors.rows; ++r) {
      const float* p = m.descriptors.ptr<float>(r);
      data.insert(data.end(), p, p + m.descriptors.cols);
      labels.push_back(std::int32_t(offset + place[std::size_t(m.labels[std::size_t(r)])]));
    }
    rows += m.descriptors.rows;
    for (std::size_t l = 0; l < m.locations.size(); ++l) label_slot.push_back(s);
  }
  // The probed search needs the vocabulary's descriptor space; targets of
  // another dimension are searched exhaustively.
  if (!labels.empty() && o.probe_words > 0 && vocab && vocab->dims() == params.dims) {
    // Each centre's word is computed once per target and kept, so a change
    // re-sorts the lists but quantises only the new targets' centres.
    std::vector<std::int32_t> cells;
    cells.reserve(labels.size());
    std::vector<WordAssignment> wa;
    for (const auto& t : slots) {
      if (!t.alive) continue;
      const Model& m = *t.model;
      if (t.cells.size() != std::size_t(m.descriptors.rows)) {
        wa.resize(std::size_t(m.descriptors.rows));
        vocab->Quantize(m.descriptors.ptr<float>(0), wa.size(), 1, wa.data());
        t.cells.resize(wa.size());
        for (std::size_t i = 0; i < wa.size(); ++i) t.cells[i] = wa[i].word;
      }
      cells.insert(cells.end(), t.cells.begin(), t.cells.end());
    }
    IvfOptions io;
    io.nprobe = o.probe_words;
    auto ivf = std::make_unique<IvfIndex>(vocab->word(0), std::size_t(vocab->size()), vocab->dims(), io);
    ivf->BuildAssigned(data.data(), labels.size(), params.dims, labels.data(), cells.data());
    index = std::move(ivf);
  } else if (!labels.empty()) {
    index = MakeIndexByName(o.match.index == "ivf" ? "exact" : o.match.index);  // exhaustive: FFVA
    index->Build(data.data(), labels.size(), params.dims, labels.data());
  }
  dirty = false;
}

namespace {

// Robust fit over one target's correspondences (as Matcher::Verify); inliers
// are counted as distinct query points, since a query point may vote for
// several locations of one target.
bool VerifyTarget(std::vector<Vote> votes, int width, int height, const RecognizerOptions& o, int min_inliers,
                  Recognition& out) {
  // PROSAC draws from the front: the most distinctive matches first. Word
  // votes carry no ratio to sort by: they take uniform sampling (kAccurate).
  const bool ranked = std::any_of(votes.begin(), votes.end(), [](const Vote& v) { return v.ratio > 0; });
  if (o.match.robust == RobustMethod::kProsac && ranked)
    std::stable_sort(votes.begin(), votes.end(), [](const Vote& a, const Vote& b) { return a.ratio < b.ratio; });
  MatchOptions mo = o.match;
  if (mo.robust == RobustMethod::kProsac && !ranked) mo.robust = RobustMethod::kAccurate;
  std::vector<cv::Point2f> src, dst;
  src.reserve(votes.size());
  dst.reserve(votes.size());
  for (const auto& v : votes) {
    src.push_back(v.object);
    dst.push_back(v.query);
  }
  if (int(votes.size()) < std::max(4, min_inliers)) return false;
  cv::theRNG().state = 0x12345678;  // reproducible RANSAC
  const GeometryFit g = FitGeometry(src, dst, mo);
  if (!g.ok || g.inliers < min_inliers) return false;
  std::vector<int> q;
  for (std::size_t i = 0; i < votes.size() && i < g.mask.size(); ++i)
    if (g.mask[i]) q.push_back(votes[i].query_index);
  std::sort(q.begin(), q.end());
  const int inl = int(std::unique(q.begin(), q.end()) - q.begin());
  if (inl < min_inliers) return false;
  const std::array<cv::Point2f, 4> quad = ProjectOutline(g.homography, width, height);
  if (!IsPlausibleOutline(quad)) return false;
  out.homography = g.homography;
  out.outline = quad;
  out.inliers = inl;
  return true;
}

// Indices of the postings within max_hamming bits of `signature`, written to
// `out` (room for list.size()); returns their number. Branch-free, and built
// twice by GCC (with the POPCNT instruction and without, chosen at load time
// by CPU), since this loop is most of a frame's search at thousands of targets.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
__attribute__((target_clones("popcnt", "default")))
#endif
std::size_t FilterPostings(const Posting* list, std::size_t size, std::uint32_t signature, int max_hamming,
                           std::uint32_t* out) {
  std::size_t m = 0;
  for (std::size_t x = 0; x < size; ++x) {
    out[m] = std::uint32_t(x);
    m += std::popcount((list[x].lo ^ signature) & kSignatureMask) <= max_hamming;
  }
  return m;
}

// Targets with enough votes to be verified and to reach min_inliers, best
// score first, at most max_candidates.
std::vector<std::uint32_t> Candidates(const std::vector<int>& count, const std::vector<float>& score,
                                      const RecognizerOptions& o) {
  const int need = std::max(o.min_votes, o.min_inliers);
  std::vector<std::uint32_t> cand;
  for (std::uint32_t s = 0; s < count.size(); ++s)
    if (count[s] >= need) cand.push_back(s);
  std::stable_sort(cand.begin(), cand.end(), [&](std::uint32_t a, std::uint32_t b) { return score[a] > score[b]; });
  if (int(cand.size()) > o.max_candidates) cand.resize(std::size_t(o.max_candidates));
  return cand;
}

}  // namespace

// The serialised form of an Encoded target (little-endian):
//   "MVKPWENC", u32 version, u32 vocabulary checksum, u32 vocabulary size,
//   u32 max_locations, u32 words_per_location, the query-side ModelParams,
//   i32 width, i32 height, u32 L, L x (u16 x, u16 y), u32 E,
//   E x (i32 word, u8 location, u32 signature), u32 crc32 of all before.
constexpr char kEncodedMagic[8] = {'M', 'V', 'K', 'P', 'W', 'E', 'N', 'C'};
constexpr std::uint32_t kEncodedVersion = 1;

struct ByteWriter {
  std::vector<std::uint8_t> out;
  template <class T>
  void Put(T v) {
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    out.insert(out.end(), p, p + sizeof(T));
  }
};

struct ByteReader {
  const std::uint8_t* p;
  std::size_t left;
  const std::string& name;
  template <class T>
  T Get() {
    if (left < sizeof(T)) throw Error(ErrorCode::kBadModel, name + ": truncated word encoding");
    T v;
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    left -= sizeof(T);
    return v;
  }
};

void PutParams(ByteWriter& w, const ModelParams& m) {
  w.Put<float>(m.smooth_sigma);
  w.Put<std::int32_t>(m.patch_size);
  w.Put<std::int32_t>(m.dims);
  w.Put<std::uint8_t>(m.orient ? 1 : 0);
  w.Put<std::int32_t>(m.orientation_radius);
  w.Put<float>(m.min_strength);
  w.Put<float>(m.relative_threshold);
  w.Put<float>(m.min_distance);
  w.Put<std::int32_t>(m.block_size);
}

ModelParams GetParams(ByteReader& r) {
  ModelParams m;
  m.smooth_sigma = r.Get<float>();
  m.patch_size = r.Get<std::int32_t>();
  m.dims = r.Get<std::int32_t>();
  m.orient = r.Get<std::uint8_t>() != 0;
  m.orientation_radius = r.Get<std::int32_t>();
  m.min_strength = r.Get<float>();
  m.relative_threshold = r.Get<float>();
  m.min_distance = r.Get<float>();
  m.block_size = r.Get<std::int32_t>();
  return m;
}

std::vector<std::uint8_t> SerializeEncoded(const Encoded& e, const Vocabulary& v, const RecognizerOptions& o) {
  ByteWriter w;
  w.out.assign(kEncodedMagic, kEncodedMagic + 8);
  w.Put<std::uint32_t>(kEncodedVersion);
  w.Put<std::uint32_t>(v.checksum());
  w.Put<std::uint32_t>(std::uint32_t(v.size()));
  w.Put<std::uint32_t>(std::uint32_t(o.max_locations));
  w.Put<std::uint32_t>(std::uint32_t(o.words_per_location));
  PutParams(w, e.params);
  w.Put<std::int32_t>(e.width);
  w.Put<std::int32_t>(e.height);
  w.Put<std::uint32_t>(std::uint32_t(e.xy.size() / 2));
  for (std::uint16_t c : e.xy) w.Put<std::uint16_t>(c);
  w.Put<std::uint32_t>(std::uint32_t(e.entries.size()));
  for (const auto& x : e.entries) {
    w.Put<std::int32_t>(x.word);
    w.Put<std::uint8_t>(std::uint8_t(x.location));
    w.Put<std::uint32_t>(x.signature);
  }
  w.Put<std::uint32_t>(Crc32(w.out.data(), w.out.size()));
  return std::move(w.out);
}

// Throws Error(kBadModel) naming `name` for a corrupt encoding, or one made
// with another vocabulary or other word settings (the caller then encodes
// the model again).
Encoded ParseEncoded(const std::uint8_t* data, std::size_t size, const Vocabulary& v, const RecognizerOptions& o,
                     const std::string& name) {
  auto bad = [&](const std::string& why) { return Error(ErrorCode::kBadModel, name + ": " + why); };
  if (size < 12 || std::memcmp(data, kEncodedMagic, 8) != 0) throw bad("not an mvkp word encoding");
  std::uint32_t crc;
  std::memcpy(&crc, data + size - 4, 4);
  if (Crc32(data, size - 4) != crc) throw bad("word encoding checksum mismatch (corrupt)");
  ByteReader r{data + 8, size - 12, name};
  if (r.Get<std::uint32_t>() != kEncodedVersion) throw bad("word encoding of another format version");
  if (r.Get<std::uint32_t>() != v.checksum() || r.Get<std::uint32_t>() != std::uint32_t(v.size()))
    throw bad("word encoding made with another vocabulary");
  if (r.Get<std::uint32_t>() != std::uint32_t(o.max_locations) ||
      r.Get<std::uint32_t>() != std::uint32_t(o.words_per_location))
    throw bad("word encoding made with other word settings");
  Encoded e;
  e.params = GetParams(r);
  e.width = r.Get<std::int32_t>();
  e.height = r.Get<std::int32_t>();
  if (e.params.dims != v.dims()) throw bad("word encoding of another descriptor size");
  if (e.width < 1 || e.height < 1 || e.width > kMaxObjectSide || e.height > kMaxObjectSide)
    throw bad("bad target size in word encoding");
  const std::uint32_t L = r.Get<std::uint32_t>();
  if (L < 1 || L > 256 || L > std::uint32_t(o.max_locations)) throw bad("bad location count in word encoding");
  e.xy.resize(2 * std::size_t(L));
  for (auto& c : e.xy) c = r.Get<std::uint16_t>();
  const std::uint32_t E = r.Get<std::uint32_t>();
  if (E > L * std::uint32_t(o.words_per_location)) throw bad("bad posting count in word encoding");
  e.entries.resize(E);
  for (auto& x : e.entries) {
    x.word = r.Get<std::int32_t>();
    x.location = r.Get<std::uint8_t>();
    x.signature = r.Get<std::uint32_t>();
    if (x.word < 0 || x.word >= v.size() || x.location >= L) throw bad("bad posting in word encoding");
  }
  if (r.left != 0) throw bad("trailing bytes in word encoding");
  return e;
}

// kExact: every ratio-test match so far, per target slot, with its ratio, and
// how many query points have been searched.
struct Recognizer::SearchState {
  struct Ranked {
    float ratio;
    Vote vote;
  };
  std::vector<std::vector<Ranked>> by_slot;
  std::size_t searched = 0;
};

Recognizer::Recognizer(const RecognizerOptions& options, const Vocabulary* vocabulary)
    : impl_(std::make_unique<Impl>()), options_(options) {
  options_.Check();
  if (options_.search == RecognizerSearch::kWords || options_.probe_words > 0) {
    Require(vocabulary == nullptr || vocabulary->dims() > 0, ErrorCode::kInvalidArgument, "recognizer: empty vocabulary");
    impl_->vocab = vocabulary ? vocabulary : &DefaultVocabulary();
    Require(!impl_->vocab->empty(), ErrorCode::kInvalidArgument, "recognizer: empty vocabulary");
  }
  if (options_.search == RecognizerSearch::kWords) impl_->lists.resize(std::size_t(impl_->vocab->size()));
}
Recognizer::~Recognizer() = default;
Recognizer::Recognizer(Recognizer&&) noexcept = default;
Recognizer& Recognizer::operator=(Recognizer&&) noexcept = default;

void Recognizer::Add(const std::string& id, const Model& model) {
  Impl& im = *impl_;
  im.RequireNewId(id);
  model.Validate("target '" + id + "'");
  im.RequireSameFeatures(id, model.params);
  const bool words = options_.search == RecognizerSearch::kWords;
  if (words) {
    Require(model.params.dims == im.vocab->dims(), ErrorCode::kInvalidArgument,
            "target '" + id + "': descriptor dims " + std::to_string(model.params.dims) +
                " differ from the vocabulary's " + std::to_string(im.vocab->dims()));
    Require(model.object_width <= kMaxObjectSide && model.object_height <= kMaxObjectSide,
            ErrorCode::kInvalidArgument, "target '" + id + "': larger than 16383 px");
  }
  Encoded e;
  if (words) {
    e = im.Encode(model, options_);  // may throw: nothing changed yet
  } else {
    e.params = model.params;
    e.width = model.object_width;
    e.height = model.object_height;
  }
  im.Insert(id, std::move(e), !words || options_.keep_models ? std::make_shared<const Model>(model) : nullptr);
  ids_.push_back(id);
}

std::vector<std::uint8_t> Recognizer::Encode(const Model& model) const {
  const Impl& im = *impl_;
  Require(options_.search == RecognizerSearch::kWords, ErrorCode::kInvalidArgument,
          "encode: only the word search has a compact encoding");
  model.Validate("model");
  Require(model.params.dims == im.vocab->dims(), ErrorCode::kInvalidArgument,
          "encode: descriptor dims differ from the vocabulary's");
  Require(model.object_width <= kMaxObjectSide && model.object_height <= kMaxObjectSide,
          ErrorCode::kInvalidArgument, "encode: target larger than 16383 px");
  return SerializeEncoded(im.Encode(model, options_), *im.vocab, options_);
}

void Recognizer::AddEncoded(const std::string& id, const std::uint8_t* data, std::size_t size) {
  Impl& im = *impl_;
  Require(options_.search == RecognizerSearch::kWords, ErrorCode::kInvalidArgument,
          "add encoded: only the word search has a compact encoding");
  im.RequireNewId(id);
  Encoded e = ParseEncoded(data, size, *im.vocab, options_, "target '" + id + "'");
  im.RequireSameFeatures(id, e.params);
  im.Insert(id, std::move(e), nullptr);
  ids_.push_back(id);
}

bool Recognizer::Remove(const std::string& id) {
  Impl& im = *impl_;
  auto it = im.by_id.find(id);
  if (it == im.by_id.end()) return false;
  const std::uint32_t slot = it->second;
  for (auto& list : im.lists)
    std::erase_if(list, [slot](const Posting& p) { return p.slot() == slot; });
  im.slots[slot] = Impl::Target{};
  im.free_slots.push_back(slot);
  im.by_id.erase(it);
  im.focus.erase(id);
  ids_.erase(std::find(ids_.begin(), ids_.end(), id));
  im.dirty = true;
  if (ids_.empty()) im.have_params = false;
  return true;
}

bool Recognizer::Contains(const std::string& id) const { return impl_->by_id.count(id) > 0; }

void Recognizer::Prepare() const {
  if (options_.search == RecognizerSearch::kExact) impl_->EnsureIndex(options_);
}

void Recognizer::ShrinkToFit() {
  for (auto& list : impl_->lists) list.shrink_to_fit();
}

RecognitionResult Recognizer::RecognizeOne(const cv::Mat& gray, const std::string& id) const {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "recognise: expected a non-empty 8-bit grayscale frame");
  const Impl& im = *impl_;
  auto found = im.by_id.find(id);
  Require(found != im.by_id.end(), ErrorCode::kInvalidArgument, "recognise: no target '" + id + "'");
  const Impl::Target& t = im.slots[found->second];
  if (!t.model) {
    // Compact focus: this target's postings only. (More signature tolerance
    // here found more frames but also wrong poses: measured, not used.)
    return Search(gray, found->second, options_);
  }
  std::shared_ptr<const Matcher> m;
  {
    std::lock_guard<std::mutex> lock(im.mutex);
    auto it = im.focus.find(id);
    if (it == im.focus.end()) {
      MatchOptions mo = options_.match;
      mo.min_inliers = options_.min_inliers;
      it = im.focus.emplace(id, std::make_shared<const Matcher>(*t.model, mo)).first;
    }
    m = it->second;
  }
  const MatchResult mr = m->Match(gray);
  RecognitionResult r;
  r.keypoints = mr.keypoints;
  r.matches = int(mr.matches.size());
  r.candidates = 1;
  r.detect_ms = mr.time.smooth_ms + mr.time.detect_ms;
  r.describe_ms = mr.time.describe_ms;
  r.search_ms = mr.time.search_ms;
  r.verify_ms = mr.time.verify_ms;
  if (mr.found) {
    Recognition x;
    x.id = id;
    x.homography = mr.homography;
    x.outline = mr.outline;
    x.inliers = mr.inliers;
    x.votes = int(mr.matches.size());
    x.score = x.votes ? double(x.inliers) / x.votes : 0.0;
    r.found.push_back(x);
  }
  return r;
}

RecognitionResult Recognizer::Recognize(const cv::Mat& gray) const { return Recognize(gray, options_.max_candidates); }

RecognitionResult Recognizer::Recognize(const cv::Mat& gray, int max_candidates) const {
  Require(!gray.empty() && gray.type() == CV_8UC1, ErrorCode::kInvalidArgument,
          "recognise: expected a non-empty 8-bit grayscale frame");
  Require(max_candidates >= 1 && max_candidates <= 100000, ErrorCode::kInvalidArgument,
          "recognise: max candidates must be in 1..100000");
  RecognizerOptions o = options_;
  o.max_candidates = max_candidates;
  const int side = std::max(gray.cols, gray.rows);
  const int work = o.match.working_size;
  if (work <= 0 || side <= work) return Search(gray, -1, o);
  // A large frame (as Matcher::Match): at the working size, then twice as
  // fine if nothing is found; homographies in the frame's pixels.
  RecognitionResult total;
  for (double f = double(work) / side;; f = std::min(1.0, 2 * f)) {
    Timer t;
    const cv::Mat img = ScaleFrameDown(gray, f);
    const double resample_ms = t.ElapsedMs();
    RecognitionResult r = Search(img, -1, o);
    const double fx = double(img.cols) / gray.cols, a = 1.0 / fx, b = 0.5 / fx - 0.5;
    const cv::Matx33d S(a, 0, b, 0, a, b, 0, 0, 1);
    for (auto& x : r.found) {
      x.homography = S * x.homography;
      x.homography *= 1.0 / x.homography(2, 2);
      for (auto& c : x.outline) c = {float(c.x * a + b), float(c.y * a + b)};
    }
    total.detect_ms += r.detect_ms + resample_ms;
    total.describe_ms += r.describe_ms;
    total.search_ms += r.search_ms;
    total.verify_ms += r.verify_ms;
    total.keypoints += r.keypoints;
    total.matches += r.matches;
    total.candidates += r.candidates;
    total.found = std::move(r.found);
    if (!total.found.empty() || f >= 1.0) break;
  }
  return total;
}

RecognitionResult Recognizer::Search(const cv::Mat& gray, std::int64_t only_slot, const RecognizerOptions& o) const {
  const Impl& im = *impl_;
  RecognitionResult r;
  if (ids_.empty()) return r;
  const bool words = o.search == RecognizerSearch::kWords;
  if (!words) im.EnsureIndex(o);

  FeatureOptions fo = QueryFeatureOptions(im.params, o.match.max_points, o.match.grid_cells, o.match.grid_share);
  Features f = ExtractFeatures(gray, fo);
  r.detect_ms = f.smooth_ms + f.detect_ms;
  r.describe_ms = f.describe_ms;
  SearchState state;
  VoteAndVerify(f, only_slot, o, state, r);
  int best = 0;
  for (const auto& x : r.found) best = std::max(best, x.inliers);
  if (best >= o.match.retry_below_inliers || o.match.half_res_points <= 0 || gray.cols < 64 || gray.rows < 64)
    return r;

  // Nothing found, or weakly: a target may appear larger than its trained
  // view range. As Matcher does, add points from half resolution, search and
  // verify again, and keep each target's better result.
  Timer th;
  cv::Mat half;
  cv::resize(gray, half, cv::Size(gray.cols / 2, gray.rows / 2), 0, 0, cv::INTER_AREA);
  r.detect_ms += th.ElapsedMs();
  fo.detector.max_points = o.match.half_res_points;
  Features g = ExtractFeatures(half, fo);
  for (auto& kp : g.keypoints) {  // half-resolution pixel centres at full resolution
    kp.x = 2 * kp.x + 0.5f;
    kp.y = 2 * kp.y + 0.5f;
  }
  r.detect_ms += g.smooth_ms + g.detect_ms;
  r.describe_ms += g.describe_ms;
  f.keypoints.insert(f.keypoints.end(), g.keypoints.begin(), g.keypoints.end());
  cv::vconcat(f.descriptors, g.descriptors, f.descriptors);
  RecognitionResult second;
  VoteAndVerify(f, only_slot, o, state, second);
  r.search_ms += second.search_ms;
  r.verify_ms += second.verify_ms;
  r.keypoints = second.keypoints;
  r.matches = second.matches;
  r.candidates += second.candidates;
  for (auto& x : second.found) {
    auto it = std::find_if(r.found.begin(), r.found.end(), [&](const Recognition& y) { return y.id == x.id; });
    if (it == r.found.end()) r.found.push_back(std::move(x));
    else if (x.inliers > it->inliers) *it = std::move(x);
  }
  std::stable_sort(r.found.begin(), r.found.end(), [](const Recognition& a, const Recognition& b) { return a.inliers > b.inliers; });
  return r;
}

void Recognizer::VoteAndVerify(const Features& f, std::int64_t only_slot, const RecognizerOptions& o,
                               SearchState& state, RecognitionResult& r) const {
  const Impl& im = *impl_;
  const bool words = o.search == RecognizerSearch::kWords;
  r.keypoints = int(f.keypoints.size());
  Timer ts;
  const std::size_t n = f.keypoints.size();
  std::vector<std::vector<Vote>> votes;  // per candidate
  std::vector<std::uint32_t> cand;       // candidate slots, best first
  std::vector<int> count(im.slots.size(), 0);
  std::vector<float> score(im.slots.size(), 0.f);  // candidate ranking
  if (words && n > 0) {
    // Tentative correspondences from the inverted file; a query point votes
    // once per target however many of its locations it hits.
    const int k = o.query_words;
    std::vector<WordAssignment> qa(n * std::size_t(k));
    im.vocab->Quantize(f.descriptors.ptr<float>(0), n, k, qa.data());
    // A vote weighs by how well the signatures agree (Hamming-embedding
    // weighting): near-identical signatures are rarely chance.
    std::vector<float> weight(std::size_t(o.max_hamming) + 1);
    const float sigma = std::max(1.f, 0.5f * float(o.max_hamming));
    for (std::size_t h = 0; h < weight.size(); ++h) weight[h] = std::exp(-float(h * h) / (2 * sigma * sigma));
    // Per query point and target, only the best-agreeing postings (fewest
    // differing signature bits, at most two) become correspondences: the
    // others are mostly wrong and would drown RANSAC's inlier ratio.
    // Two passes over the same postings: the first only counts votes (per
    // target state, no allocation), the second collects correspondences for
    // the candidates alone, since at thousands of targets almost all hits
    // are chance and storing them would cost more than scanning twice.
    std::vector<std::int32_t> stamp(im.slots.size(), -1);
    std::vector<std::uint8_t> best_h(im.slots.size());
    std::vector<std::uint32_t> loc1(im.slots.size()), loc2(im.slots.size());
    std::vector<std::uint32_t> touched, passing;
    auto scan = [&](const std::vector<std::int32_t>* cand_index) {
      std::fill(stamp.begin(), stamp.end(), -1);
      for (std::size_t i = 0; i < n; ++i) {
        touched.clear();
        for (int j = 0; j < k; ++j) {
          const WordAssignment& a = qa[i * std::size_t(k) + std::size_t(j)];
          if (a.word < 0) continue;
          const auto& list = im.lists[std::size_t(a.word)];
          if (passing.size() < list.size()) passing.resize(list.size());
          const std::size_t m = FilterPostings(list.data(), list.size(), a.signature, o.max_hamming, passing.data());
          for (std::size_t x = 0; x < m; ++x) {
            const Posting& p = list[passing[x]];
            const int h = std::popcount(p.signature() ^ (a.signature & kSignatureMask));
            const std::uint32_t slot = p.slot();
            if (only_slot >= 0 && slot != std::uint64_t(only_slot)) continue;
            if (cand_index && (*cand_index)[slot] < 0) continue;
            const std::uint32_t loc = p.location();
            if (stamp[slot] != std::int32_t(i)) {
              stamp[slot] = std::int32_t(i);
              best_h[slot] = std::uint8_t(h);
              loc1[slot] = loc;
              loc2[slot] = 0xffffffffu;
              touched.push_back(slot);
            } else if (h < best_h[slot]) {
              best_h[slot] = std::uint8_t(h);
              loc1[slot] = loc;
              loc2[slot] = 0xffffffffu;
            } else if (h == best_h[slot] && loc2[slot] == 0xffffffffu && loc != loc1[slot]) {
              loc2[slot] = loc;
            }
          }
        }
        const cv::Point2f q(f.keypoints[i].x, f.keypoints[i].y);
        for (std::uint32_t slot : touched) {
          if (!cand_index) {
            ++count[slot];
            ++r.matches;
            score[slot] += weight[best_h[slot]];
            continue;
          }
          auto& v = votes[std::size_t((*cand_index)[slot])];
          v.push_back({im.slots[slot].location(int(loc1[slot])), q, int(i)});
          if (loc2[slot] != 0xffffffffu) v.push_back({im.slots[slot].location(int(loc2[slot])), q, int(i)});
        }
      }
    };
    scan(nullptr);
    cand = Candidates(count, score, o);
    std::vector<std::int32_t> cand_index(im.slots.size(), -1);
    for (std::size_t c = 0; c < cand.size(); ++c) cand_index[cand[c]] = std::int32_t(c);
    votes.assign(cand.size(), {});
    if (!cand.empty()) scan(&cand_index);
  } else if (n > 0 && im.index) {
    // Nearest centre and nearest centre of another location (of any target),
    // ratio test on L2 distances; each kept match votes for its target.
    // With match.dynamic_goal > 0 each target gets its own ratio (thesis
    // §6.3.1, "dynamic threshold"): its matches up to ratio_min always count,
    // then the next best by ratio, up to ratio_max, until it has dynamic_goal
    // of them. A plain painting then keeps enough correspondences and a
    // textured one is not flooded.
    // Only the points not searched yet (the half-resolution retry adds some).
    const bool dynamic = o.match.dynamic_goal > 0;
    const float ratio = dynamic ? o.match.ratio_max : o.match.ratio;
    using Ranked = SearchState::Ranked;
    auto& found_by_slot = state.by_slot;
    found_by_slot.resize(im.slots.size());
    const std::size_t first = std::min(state.searched, n), m = n - first;
    std::vector<Neighbor> nn(2 * m);
    if (m > 0) im.index->SearchTwoDistinctBatch(f.descriptors.ptr<float>(int(first)), m, nn.data(), ratio);
    for (std::size_t q = 0; q < m; ++q) {
      const std::size_t i = first + q;
      const Neighbor& a = nn[2 * q];
      const Neighbor& b = nn[2 * q + 1];
      if (a.id < 0) continue;
      const float d1 = std::sqrt(a.distance);
      const float d2 = b.id < 0 ? std::numeric_limits<float>::infinity() : std::sqrt(b.distance);
      if (!(d1 < ratio * d2)) continue;
      const std::uint32_t slot = im.label_slot[std::size_t(a.label)];
      const Model& model = *im.slots[slot].model;
      const auto& loc = model.locations[std::size_t(model.labels[std::size_t(a.id - im.row_offset[slot])])];
      const float ratio_here = d2 > 0 ? d1 / d2 : 0.f;
      found_by_slot[slot].push_back(
          {ratio_here, {{loc.x, loc.y}, {f.keypoints[i].x, f.keypoints[i].y}, int(i), ratio_here}});
    }
    state.searched = n;
    std::vector<std::vector<Ranked>> by_slot(im.slots.size());
    for (std::size_t sl = 0; sl < by_slot.size(); ++sl) {
      auto& v = by_slot[sl];
      v = found_by_slot[sl];
      if (dynamic) {
        std::stable_sort(v.begin(), v.end(), [](const Ranked& x, const Ranked& y) { return x.ratio < y.ratio; });
        std::size_t keep = 0;
        while (keep < v.size() && (v[keep].ratio < o.match.ratio_min || int(keep) < o.match.dynamic_goal)) ++keep;
        v.resize(keep);
      }
      count[sl] = int(v.size());
      score[sl] = float(v.size());
      r.matches += int(v.size());
    }
    cand = Candidates(count, score, o);
    for (std::uint32_t c : cand) {
      votes.emplace_back();
      for (const auto& x : by_slot[c]) votes.back().push_back(x.vote);
    }
  }
  r.search_ms = ts.ElapsedMs();

  Timer tv;
  r.candidates = int(cand.size());
  for (std::size_t c = 0; c < cand.size(); ++c) {
    const std::uint32_t s = cand[c];
    const Impl::Target& t = im.slots[s];
    Recognition rec;
    if (VerifyTarget(votes[c], t.width, t.height, o, o.min_inliers, rec)) {
      rec.id = t.id;
      rec.votes = count[s];
      rec.score = std::min(1.0, double(rec.inliers) / double(count[s]));
      r.found.push_back(std::move(rec));
    }
  }
  std::stable_sort(r.found.begin(), r.found.end(), [](const Recognition& a, const Recognition& b) { return a.inliers > b.inliers; });
  r.verify_ms = tv.ElapsedMs();
}

std::size_t Recognizer::memory_bytes() const {
  const Impl& im = *impl_;
  std::size_t bytes = 0;
  if (options_.search == RecognizerSearch::kExact) {
    im.EnsureIndex(options_);
    if (im.index) bytes += im.index->memory_bytes();
    bytes += im.label_slot.capacity() * sizeof(std::uint32_t) + im.row_offset.capacity() * sizeof(std::int32_t);
  }
  for (const auto& list : im.lists) bytes += list.capacity() * sizeof(Posting);
  for (const auto& t : im.slots) {
    bytes += sizeof(Impl::Target) + t.id.capacity() + t.xy.capacity() * sizeof(std::uint16_t);
    if (t.model)
      bytes += sizeof(Model) + t.model->descriptors.total() * t.model->descriptors.elemSize() +
               t.model->labels.capacity() * sizeof(std::int32_t) +
               t.model->locations.capacity() * sizeof(ObjectLocation);
  }
  // The id map: a node per target (key, slot, hash and links).
  bytes += im.by_id.size() * (sizeof(std::string) + sizeof(std::uint32_t) + 3 * sizeof(void*)) +
           im.by_id.bucket_count() * sizeof(void*);
  for (const auto& id : ids_) bytes += sizeof(std::string) + id.capacity();
  return bytes;
}

std::size_t Recognizer::shared_bytes() const {
  const Impl& im = *impl_;
  return (im.vocab ? im.vocab->memory_bytes() : 0) + im.lists.capacity() * sizeof(std::vector<Posting>);
}

}  // namespace mvkp
