#include "mvkp/recognize/vocabulary.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>

#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/knn_index.h"

namespace mvkp {

namespace {

constexpr char kMagic[8] = {'M', 'V', 'K', 'P', 'V', 'O', 'C', 'B'};
constexpr std::uint32_t kVersion = 1;

std::unique_ptr<KnnIndex> BuildIndex(const std::vector<float>& words, int dims) {
  auto index = MakeIndexByName("exact");
  index->Build(words.data(), words.size() / std::size_t(dims), dims, nullptr);
  return index;
}

void PutU32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(std::uint8_t(v >> (8 * i)));
}
std::uint32_t GetU32(const std::uint8_t* p) {
  return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}

}  // namespace

Vocabulary::Vocabulary() = default;
Vocabulary::~Vocabulary() = default;
Vocabulary::Vocabulary(Vocabulary&&) noexcept = default;
Vocabulary& Vocabulary::operator=(Vocabulary&&) noexcept = default;

Vocabulary::Vocabulary(std::vector<float> words, int dims) : dims_(dims), words_(std::move(words)) {
  Require(dims >= 1 && dims <= 256, ErrorCode::kInvalidArgument, "vocabulary: dims must be in 1..256");
  Require(!words_.empty() && words_.size() % std::size_t(dims) == 0, ErrorCode::kInvalidArgument,
          "vocabulary: expected a non-empty words x dims array");
  Require(words_.size() / std::size_t(dims) < std::size_t(1) << 31, ErrorCode::kInvalidArgument,
          "vocabulary: too many words");
  for (float v : words_) Require(std::isfinite(v), ErrorCode::kInvalidArgument, "vocabulary: non-finite value");
  checksum_ = Crc32(words_.data(), words_.size() * sizeof(float));
  index_ = BuildIndex(words_, dims_);
}

void Vocabulary::Quantize(const float* x, std::size_t n, int k, WordAssignment* out) const {
  Require(index_ != nullptr, ErrorCode::kInvalidArgument, "vocabulary: empty");
  Require(k >= 1 && k <= size(), ErrorCode::kInvalidArgument, "vocabulary: k out of range");
  std::vector<Neighbor> nn(n * std::size_t(k));
  if (n) index_->SearchBatch(x, n, k, nn.data());
  for (std::size_t i = 0; i < n; ++i)
    for (int j = 0; j < k; ++j) {
      const Neighbor& a = nn[i * std::size_t(k) + std::size_t(j)];
      WordAssignment& w = out[i * std::size_t(k) + std::size_t(j)];
      w.word = a.id;
      w.distance = a.distance;
      w.signature = a.id >= 0 ? Signature(x + i * std::size_t(dims_), a.id) : 0;
    }
}

std::uint32_t Vocabulary::Signature(const float* x, int w) const {
  const float* c = word(w);
  std::uint32_t s = 0;
  const int bits = std::min(dims_, 32);
  for (int j = 0; j < bits; ++j) s |= std::uint32_t(x[j] > c[j]) << j;
  return s;
}

std::size_t Vocabulary::memory_bytes() const {
  return words_.size() * sizeof(float) + (index_ ? index_->memory_bytes() : 0);
}

std::vector<std::uint8_t> Vocabulary::Serialize() const {
  std::vector<std::uint8_t> out(kMagic, kMagic + 8);
  PutU32(out, kVersion);
  PutU32(out, std::uint32_t(dims_));
  PutU32(out, std::uint32_t(size()));
  const auto* p = reinterpret_cast<const std::uint8_t*>(words_.data());
  out.insert(out.end(), p, p + words_.size() * sizeof(float));
  PutU32(out, Crc32(out.data(), out.size()));
  return out;
}

Vocabulary Vocabulary::Deserialize(const std::uint8_t* data, std::size_t size, const std::string& name) {
  auto bad = [&](const std::string& why) { return Error(ErrorCode::kBadModel, name + ": " + why); };
  if (size < 24 || std::memcmp(data, kMagic, 8) != 0) throw bad("not an mvkp vocabulary");
  const std::uint32_t version = GetU32(data + 8), dims = GetU32(data + 12), words = GetU32(data + 16);
  if (version != kVersion) throw bad("vocabulary format version " + std::to_string(version) + " is not supported");
  if (dims < 1 || dims > 256 || words < 1 || words > (1u << 24)) throw bad("bad vocabulary header");
  const std::size_t floats = std::size_t(dims) * words;
  if (size != 20 + floats * sizeof(float) + 4) throw bad("truncated or oversized vocabulary");
  if (Crc32(data, size - 4) != GetU32(data + size - 4)) throw bad("vocabulary checksum mismatch (corrupt file)");
  std::vector<float> w(floats);
  std::memcpy(w.data(), data + 20, floats * sizeof(float));
  for (float v : w)
    if (!std::isfinite(v)) throw bad("non-finite value in vocabulary");
  return Vocabulary(std::move(w), int(dims));
}

void VocabularyTrainOptions::Check() const {
  Require(words >= 1 && words <= (1 << 24), ErrorCode::kInvalidArgument, "vocabulary words must be in 1..16777216");
  Require(iterations >= 0 && iterations <= 1000, ErrorCode::kInvalidArgument, "iterations must be in 0..1000");
}

Vocabulary TrainVocabulary(const float* samples, std::size_t n, int dims, const VocabularyTrainOptions& o) {
  o.Check();
  Require(dims >= 1 && dims <= 256, ErrorCode::kInvalidArgument, "vocabulary: dims must be in 1..256");
  Require(n >= std::size_t(o.words), ErrorCode::kInvalidArgument,
          "vocabulary: " + std::to_string(n) + " samples for " + std::to_string(o.words) + " words; need at least as many");
  const std::size_t d = std::size_t(dims), k = std::size_t(o.words);
  // k-means++ seeding (Arthur & Vassilvitskii 2007): each new centre is a
  // sample drawn with probability proportional to its squared distance to the
  // nearest centre so far, so separated clusters each get a centre.
  std::mt19937_64 rng(o.seed);
  std::vector<float> centres(k * d);
  std::vector<double> d2(n, std::numeric_limits<double>::infinity());
  std::size_t pick = std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
  for (std::size_t c = 0; c < k; ++c) {
    std::memcpy(&centres[c * d], samples + pick * d, d * sizeof(float));
    const float* cc = &centres[c * d];
    double total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const float* x = samples + i * d;
      float s = 0;
      for (std::size_t j = 0; j < d; ++j) s += (x[j] - cc[j]) * (x[j] - cc[j]);
      d2[i] = std::min(d2[i], double(s));
      total += d2[i];
    }
    if (c + 1 == k) break;
    if (total <= 0) {  // fewer distinct samples than words: any sample
      pick = std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
      continue;
    }
    double u = std::uniform_real_distribution<double>(0, total)(rng);
    pick = n - 1;
    for (std::size_t i = 0; i < n; ++i) {
      u -= d2[i];
      if (u < 0) {
        pick = i;
        break;
      }
    }
  }

  std::vector<Neighbor> nn(n);
  std::vector<double> sum(k * d);
  std::vector<std::size_t> count(k);
  for (int it = 0; it < o.iterations; ++it) {
    auto index = BuildIndex(centres, dims);
    index->SearchBatch(samples, n, 1, nn.data());
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t c = std::size_t(nn[i].id);
      ++count[c];
      for (std::size_t j = 0; j < d; ++j) sum[c * d + j] += samples[i * d + j];
    }
    // Empty clusters take the samples farthest from their centres, farthest first.
    std::vector<std::size_t> far;
    for (std::size_t c = 0; c < k; ++c)
      if (count[c] == 0) far.push_back(c);
    std::vector<std::size_t> by_distance;
    if (!far.empty()) {
      by_distance.resize(n);
      std::iota(by_distance.begin(), by_distance.end(), std::size_t(0));
      std::partial_sort(by_distance.begin(), by_distance.begin() + std::ptrdiff_t(far.size()), by_distance.end(),
                        [&](std::size_t a, std::size_t b) {
                          return nn[a].distance > nn[b].distance || (nn[a].distance == nn[b].distance && a < b);
                        });
    }
    for (std::size_t c = 0; c < k; ++c) {
      if (count[c] == 0) continue;
      for (std::size_t j = 0; j < d; ++j) centres[c * d + j] = float(sum[c * d + j] / double(count[c]));
    }
    for (std::size_t e = 0; e < far.size(); ++e)
      std::memcpy(&centres[far[e] * d], samples + by_distance[e] * d, d * sizeof(float));
  }
  return Vocabulary(std::move(centres), dims);
}

}  // namespace mvkp
