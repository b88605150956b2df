// JSON parsing with limits, for every JSON text mvkp takes from outside:
// request bodies, stored exhibit metadata, `db import` lists.
//
// nlohmann::json parses iteratively, but copying, dumping and comparing a
// value recurse once per nesting level: a text nested 100 000 levels deep
// parses fine and then overflows the stack wherever it is used. So depth is
// refused while parsing, before any deep value exists, and so is size.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace mvkp {

struct JsonLimits {
  int max_depth = 32;                      // nesting of arrays/objects; the top level is depth 1
  std::size_t max_bytes = 1 << 20;         // length of the text
  std::size_t max_string_bytes = 1 << 16;  // any one string (keys included)
};

// Limits for exhibit metadata (`meta`): small, shallow objects.
inline JsonLimits MetaJsonLimits() { return {16, 64 << 10, 16 << 10}; }

// Parses `text` or throws mvkp::Error(kInvalidArgument) whose message starts
// with `what` and says what is wrong (syntax and where, too deep, too long).
nlohmann::json ParseJsonLimited(std::string_view text, const JsonLimits& limits = {},
                                const std::string& what = "JSON");

// The same, but returns false (and leaves `out` null) instead of throwing.
bool TryParseJsonLimited(std::string_view text, nlohmann::json& out, const JsonLimits& limits = {});

}  // namespace mvkp
