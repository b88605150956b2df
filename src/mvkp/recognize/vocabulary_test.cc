#include "mvkp/recognize/vocabulary.h"

#include <bit>
#include <random>

#include <gtest/gtest.h>

#include "mvkp/core/error.h"

namespace mvkp {
namespace {

std::vector<float> RandomVectors(std::size_t n, int dims, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.f, 1.f);
  std::vector<float> v(n * std::size_t(dims));
  for (auto& x : v) x = g(rng);
  return v;
}

float Dist2(const float* a, const float* b, int d) {
  float s = 0;
  for (int j = 0; j < d; ++j) s += (a[j] - b[j]) * (a[j] - b[j]);
  return s;
}

TEST(Vocabulary, QuantizeReturnsTheBruteForceNearestWordsAndTheirSignatures) {
  const int dims = 20;
  const Vocabulary v(RandomVectors(500, dims, 1), dims);
  const auto q = RandomVectors(200, dims, 2);
  std::vector<WordAssignment> out(200 * 2);
  v.Quantize(q.data(), 200, 2, out.data());
  for (std::size_t i = 0; i < 200; ++i) {
    std::vector<std::pair<float, int>> all;
    for (int w = 0; w < v.size(); ++w) all.push_back({Dist2(&q[i * dims], v.word(w), dims), w});
    std::sort(all.begin(), all.end());
    EXPECT_EQ(out[2 * i].word, all[0].second);
    EXPECT_EQ(out[2 * i + 1].word, all[1].second);
    EXPECT_FLOAT_EQ(out[2 * i].distance, all[0].first);
    std::uint32_t sig = 0;
    for (int j = 0; j < dims; ++j) sig |= std::uint32_t(q[i * dims + j] > v.word(all[0].second)[j]) << j;
    EXPECT_EQ(out[2 * i].signature, sig);
  }
}

TEST(Vocabulary, SignaturesOfNearbyVectorsDifferInFewerBitsThanOfUnrelatedOnes) {
  const int dims = 20;
  const Vocabulary v(RandomVectors(64, dims, 3), dims);
  std::mt19937_64 rng(4);
  std::normal_distribution<float> g(0.f, 1.f);
  double near = 0, far = 0;
  const int n = 2000;
  for (int i = 0; i < n; ++i) {
    auto a = RandomVectors(1, dims, 100 + i), b = a, c = RandomVectors(1, dims, 100000 + i);
    for (auto& x : b) x += 0.1f * g(rng);
    WordAssignment wa;
    v.Quantize(a.data(), 1, 1, &wa);
    near += std::popcount(wa.signature ^ v.Signature(b.data(), wa.word));
    far += std::popcount(wa.signature ^ v.Signature(c.data(), wa.word));
  }
  EXPECT_LT(near / n, 0.5 * far / n);
}

TEST(Vocabulary, TrainingRecoversWellSeparatedClusters) {
  const int dims = 8, k = 16;
  const auto centres = RandomVectors(k, dims, 5);
  std::vector<float> samples;
  std::mt19937_64 rng(6);
  std::normal_distribution<float> g(0.f, 0.01f);
  for (int i = 0; i < 4000; ++i)
    for (int j = 0; j < dims; ++j) samples.push_back(10 * centres[std::size_t(i % k) * dims + j] + g(rng));
  VocabularyTrainOptions o;
  o.words = k;
  o.iterations = 20;
  const Vocabulary v = TrainVocabulary(samples.data(), 4000, dims, o);
  ASSERT_EQ(v.size(), k);
  // Every true centre has a word within the noise.
  for (int c = 0; c < k; ++c) {
    std::vector<float> t(dims);
    for (int j = 0; j < dims; ++j) t[std::size_t(j)] = 10 * centres[std::size_t(c) * dims + j];
    WordAssignment wa;
    v.Quantize(t.data(), 1, 1, &wa);
    EXPECT_LT(wa.distance, 0.01f) << c;
  }
  // Deterministic for a seed.
  const Vocabulary w = TrainVocabulary(samples.data(), 4000, dims, o);
  EXPECT_EQ(v.checksum(), w.checksum());
  o.words = 4001;
  EXPECT_THROW(TrainVocabulary(samples.data(), 4000, dims, o), Error);
}

TEST(Vocabulary, SerializationRoundTripsAndRejectsCorruption) {
  const Vocabulary v(RandomVectors(100, 20, 7), 20);
  auto bytes = v.Serialize();
  const Vocabulary w = Vocabulary::Deserialize(bytes.data(), bytes.size(), "x");
  EXPECT_EQ(w.size(), 100);
  EXPECT_EQ(w.dims(), 20);
  EXPECT_EQ(w.checksum(), v.checksum());
  auto corrupt = bytes;
  corrupt[100] ^= 1;
  EXPECT_THROW(Vocabulary::Deserialize(corrupt.data(), corrupt.size(), "x"), Error);
  EXPECT_THROW(Vocabulary::Deserialize(bytes.data(), bytes.size() - 1, "x"), Error);
  EXPECT_THROW(Vocabulary::Deserialize(bytes.data(), 10, "x"), Error);
  std::vector<std::uint8_t> other(bytes.size(), 0);
  EXPECT_THROW(Vocabulary::Deserialize(other.data(), other.size(), "x"), Error);
}

TEST(Vocabulary, RejectsBadInput) {
  EXPECT_THROW(Vocabulary({}, 20), Error);
  EXPECT_THROW(Vocabulary(std::vector<float>(21, 0.f), 20), Error);
  EXPECT_THROW(Vocabulary(std::vector<float>{std::nanf("")}, 1), Error);
}

TEST(Vocabulary, TheBuiltInVocabularyIsTwentyDimensional) {
  const Vocabulary& v = DefaultVocabulary();
  EXPECT_EQ(v.dims(), 20);
  EXPECT_GE(v.size(), 1024);
}

}  // namespace
}  // namespace mvkp
