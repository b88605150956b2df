// mvkp::ParseJsonLimited (mvkp/db/json_limits.h), under small limits: what it
// returns is within them (depth, string lengths) and survives what callers do
// with a value (dump, copy, compare, parse again), or it throws mvkp::Error.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"

namespace {

using Json = nlohmann::json;

// Nesting of arrays and objects (a scalar is 0), and the longest string.
void Measure(const Json& j, int depth, int& max_depth, std::size_t& max_string) {
  if (j.is_string()) max_string = std::max(max_string, j.get_ref<const std::string&>().size());
  if (!j.is_structured()) return;
  max_depth = std::max(max_depth, depth + 1);
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (j.is_object()) max_string = std::max(max_string, it.key().size());
    Measure(*it, depth + 1, max_depth, max_string);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  mvkp::JsonLimits limits;
  limits.max_depth = 8;
  limits.max_bytes = 4096;
  limits.max_string_bytes = 64;
  Json j;
  try {
    j = mvkp::ParseJsonLimited(text, limits, "fuzz");
  } catch (const mvkp::Error&) {
    Json none;
    if (mvkp::TryParseJsonLimited(text, none, limits) || !none.is_null()) std::abort();
    return 0;
  }
  int depth = 0;
  std::size_t longest = 0;
  Measure(j, 0, depth, longest);
  if (size > limits.max_bytes || depth > limits.max_depth || longest > limits.max_string_bytes) std::abort();
  // Dumped and parsed again (with the default limits), it is the same value.
  const std::string dumped = j.dump();
  const Json again = mvkp::ParseJsonLimited(dumped, {}, "dump");
  if (again != j) std::abort();
  return 0;
}
