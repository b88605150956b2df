// A visual vocabulary for recognition among many targets (issue 6, SPEC §8's
// "two-stage" search): K words in descriptor space (k-means centres), each
// descriptor quantised to its nearest word plus a Hamming-embedding signature
// (Jégou, Douze & Schmid, ECCV 2008): bit j says on which side of the word's
// centre the descriptor lies in dimension j. Two descriptors in the same word
// whose signatures differ in few bits are close; ones that differ in many are
// not, so the signature restores most of the precision the quantisation loses
// at 4 bytes per stored feature instead of 80.
//
// The vocabulary is generic (trained once on images unrelated to any target,
// `mvkp vocab train`), so targets can be added and removed without retraining
// it or each other. DefaultVocabulary() is the one built into the library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace mvkp {

class KnnIndex;

struct WordAssignment {
  std::int32_t word = -1;
  std::uint32_t signature = 0;  // bit j (j < min(dims, 32)): x_j > word_j
  float distance = 0;           // squared L2 to the word
};

class Vocabulary {
 public:
  Vocabulary();
  // `words` holds size x dims floats, row-major. Throws Error(kInvalidArgument)
  // for no words, dims outside 1..256, a size mismatch or non-finite values.
  Vocabulary(std::vector<float> words, int dims);
  ~Vocabulary();
  Vocabulary(Vocabulary&&) noexcept;
  Vocabulary& operator=(Vocabulary&&) noexcept;

  int size() const { return dims_ ? int(words_.size() / std::size_t(dims_)) : 0; }
  int dims() const { return dims_; }
  bool empty() const { return words_.empty(); }
  const float* word(int i) const { return words_.data() + std::size_t(i) * std::size_t(dims_); }
  // CRC-32 of the words: identifies the vocabulary an encoding was made with.
  std::uint32_t checksum() const { return checksum_; }

  // The k nearest words (exact) of each of n descriptors (row-major, dims
  // floats each), nearest first: out holds n*k entries.
  void Quantize(const float* x, std::size_t n, int k, WordAssignment* out) const;
  // The signature of x relative to word w.
  std::uint32_t Signature(const float* x, int w) const;

  std::size_t memory_bytes() const;

  // File layout: "MVKPVOCB", u32 version, u32 dims, u32 size, floats, u32 crc32
  // of everything before it. Deserialize throws Error(kBadModel) naming `name`.
  std::vector<std::uint8_t> Serialize() const;
  static Vocabulary Deserialize(const std::uint8_t* data, std::size_t size, const std::string& name);

 private:
  int dims_ = 0;
  std::vector<float> words_;
  std::uint32_t checksum_ = 0;
  std::unique_ptr<KnnIndex> index_;  // FFVA over the words
};

struct VocabularyTrainOptions {
  int words = 1024;
  int iterations = 12;
  std::uint64_t seed = 1;
  void Check() const;
};

// k-means over n samples (row-major, dims floats each): k-means++ seeding
// (O(n * words * dims)), Lloyd iterations with the assignment done by an
// exact FFVA index over the current centres; an emptied cluster takes the
// sample farthest from its centre. Deterministic for a seed. Throws
// Error(kInvalidArgument) if n < words.
Vocabulary TrainVocabulary(const float* samples, std::size_t n, int dims, const VocabularyTrainOptions& options = {});

// The vocabulary built into the library (data/vocabulary/wh20.vocab: 20-D WH
// descriptors of the default feature settings).
const Vocabulary& DefaultVocabulary();

}  // namespace mvkp
