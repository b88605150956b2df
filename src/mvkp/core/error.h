// Errors that mvkp reports to its users.
//
// Two tiers, as in FAISS: internal invariants use assert(); anything a user
// can cause (a bad file, a bad option) throws mvkp::Error with a message that
// names the offending input. The CLI prints what() on one line and exits 1.
#pragma once

#include <stdexcept>
#include <string>

namespace mvkp {

enum class ErrorCode {
  kInvalidArgument,  // an option or argument is out of range
  kIo,               // a file is missing, unreadable or cannot be written
  kBadImage,         // not an image, truncated, empty, too small or too large
  kBadModel,         // a model file is corrupt, truncated or of another version
  kNoTexture,        // a target has too little texture to train on
  kBadIndex,         // an index or vector file is corrupt, truncated or of another version
};

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message)
      : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

// Throws Error(code, message) when cond is false. For user-facing checks only.
inline void Require(bool cond, ErrorCode code, const std::string& message) {
  if (!cond) throw Error(code, message);
}

}  // namespace mvkp
