// The vocabulary built into the library: data/vocabulary/wh20.vocab, linked
// in as read-only data (.incbin), so no file has to be found at run time.
// Made by scripts/make-vocabulary.sh (`mvkp vocab train` over images that no
// evaluation uses).
#include <mutex>

#include "mvkp/core/error.h"
#include "mvkp/recognize/vocabulary.h"

#ifdef MVKP_VOCAB_FILE
__asm__(".section .rodata\n"
        ".balign 16\n"
        ".type mvkp_default_vocab_begin, @object\n"
        "mvkp_default_vocab_begin:\n"
        ".incbin \"" MVKP_VOCAB_FILE "\"\n"
        ".type mvkp_default_vocab_end, @object\n"
        "mvkp_default_vocab_end:\n"
        ".previous\n");
extern "C" const unsigned char mvkp_default_vocab_begin[];
extern "C" const unsigned char mvkp_default_vocab_end[];
#endif

namespace mvkp {

const Vocabulary& DefaultVocabulary() {
  static const Vocabulary* vocab = [] {
#ifdef MVKP_VOCAB_FILE
    return new Vocabulary(Vocabulary::Deserialize(mvkp_default_vocab_begin,
                                                  std::size_t(mvkp_default_vocab_end - mvkp_default_vocab_begin),
                                                  "built-in vocabulary"));
#else
    return new Vocabulary();
#endif
  }();
  Require(!vocab->empty(), ErrorCode::kInvalidArgument,
          "this build has no default vocabulary (data/vocabulary/wh20.vocab was missing); give one explicitly");
  return *vocab;
}

}  // namespace mvkp
