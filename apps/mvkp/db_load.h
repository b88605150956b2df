// Loading a target database into a recogniser (recognize, video).
#pragma once

#include <functional>
#include <string>

#include "mvkp/db/target_store.h"
#include "mvkp/recognize/recognizer.h"

namespace mvkp::cli {

// The kind under which `db add` / `db import` store Recognizer::Encode bytes.
constexpr const char* kWordsEncoding = "words";

// Adds every target of `store` to `rec` and calls `each(info, width, height)`
// (the target's size in its model's pixels) for it. The word search takes the
// stored encodings that fit its vocabulary and settings and decodes only the
// other targets' models (older databases, other settings); the exact search
// decodes every model. Returns the number of targets that came from
// encodings. Errors name `db` and the target.
std::size_t LoadTargets(const TargetStore& store, Recognizer& rec, const std::string& db,
                        const std::function<void(const TargetInfo&, int, int)>& each);

}  // namespace mvkp::cli
