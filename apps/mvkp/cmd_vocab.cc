// mvkp vocab: train / inspect the visual vocabulary of the word-based
// recogniser (src/mvkp/recognize/vocabulary.h).
#include <unistd.h>

#include <cstdio>
#include <memory>

#include "commands.h"
#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/recognize/vocabulary.h"
#include "mvkp/train/trainer.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct VocabArgs {
  std::vector<std::string> images;
  std::string out, file;
  VocabularyTrainOptions opt;
  TrainOptions train;
};

// The k-means centres of every image's model are the samples: they summarise
// how each point looks over many affine views, as the targets' postings will.
int RunVocabTrain(VocabArgs& a) {
  a.opt.Check();
  Require(!a.out.empty(), ErrorCode::kInvalidArgument, "vocab train: -o OUT is required");
  Timer t;
  std::vector<float> samples;
  int dims = 0;
  const bool progress = ::isatty(2);  // a progress line on a terminal only, not in logs
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    const cv::Mat gray = LoadImageGray(a.images[i]);
    const Model m = TrainNamed(a.images[i], gray, a.train);
    dims = m.descriptors.cols;
    for (int r = 0; r < m.descriptors.rows; ++r)
      samples.insert(samples.end(), m.descriptors.ptr<float>(r), m.descriptors.ptr<float>(r) + dims);
    if (progress)
      std::fprintf(stderr, "\r%zu/%zu images, %zu samples", i + 1, a.images.size(), samples.size() / std::size_t(dims));
  }
  if (progress) std::fprintf(stderr, "\n");
  const std::size_t n = samples.size() / std::size_t(dims);
  const Vocabulary v = TrainVocabulary(samples.data(), n, dims, a.opt);
  const std::vector<std::uint8_t> bytes = v.Serialize();
  WriteFileAtomically(a.out, bytes.data(), bytes.size());
  std::printf("vocabulary of %d words (%d-D) from %zu samples of %zu images: %s (%.1f KB, crc %08x) in %.1f s\n",
              v.size(), v.dims(), n, a.images.size(), a.out.c_str(), bytes.size() / 1024.0, v.checksum(),
              t.ElapsedMs() / 1000.0);
  return 0;
}

int RunVocabInfo(const VocabArgs& a) {
  const std::vector<std::uint8_t> bytes = ReadFileBytes(a.file);
  const Vocabulary v = Vocabulary::Deserialize(bytes.data(), bytes.size(), a.file);
  std::printf("%s: %d words, %d-D, crc %08x\n", a.file.c_str(), v.size(), v.dims(), v.checksum());
  return 0;
}

}  // namespace

void RegisterVocab(CLI::App& app, int* code) {
  auto a = std::make_shared<VocabArgs>();
  auto* v = app.add_subcommand("vocab", "Train or inspect the visual vocabulary of the word-based recogniser");
  v->require_subcommand(1);
  auto* tr = v->add_subcommand("train", "k-means over the model centres of training images (unrelated to any target)");
  tr->add_option("IMAGE", a->images, "training images")->required();
  tr->add_option("-o,--out", a->out, "vocabulary file to write")->required();
  tr->add_option("--words", a->opt.words, "vocabulary size")->capture_default_str();
  tr->add_option("--iterations", a->opt.iterations, "k-means iterations")->capture_default_str();
  tr->add_option("--vocab-seed", a->opt.seed, "k-means seed of the vocabulary")->capture_default_str();
  AddTrainOptions(tr, &a->train);
  tr->callback([a, code] { *code = RunVocabTrain(*a); });
  auto* info = v->add_subcommand("info", "Check a vocabulary file and print its size");
  info->add_option("FILE", a->file, "vocabulary file")->required();
  info->callback([a, code] { *code = RunVocabInfo(*a); });
}

}  // namespace mvkp::cli
