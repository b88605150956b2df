// The target lists of `mvkp db import` (mvkp/db/target_list.h): the input is
// parsed as CSV and as JSON; each gives entries with an id and an image, and
// a meta that is a JSON object within the metadata limits, or throws
// mvkp::Error.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"
#include "mvkp/db/target_list.h"

namespace {

void Parse(std::string_view text, mvkp::TargetListFormat format) {
  mvkp::TargetListLimits limits;
  limits.max_bytes = 1 << 20;
  limits.max_entries = 1000;
  std::vector<mvkp::TargetListEntry> list;
  try {
    list = mvkp::ParseTargetList(text, format, "fuzz", limits);
  } catch (const mvkp::Error&) {
    return;
  }
  if (list.size() > limits.max_entries) std::abort();
  for (const auto& [info, image] : list) {
    if (info.id.empty() || image.empty()) std::abort();
    nlohmann::json meta;
    if (!mvkp::TryParseJsonLimited(info.meta, meta, mvkp::MetaJsonLimits()) || !meta.is_object()) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  Parse(text, mvkp::TargetListFormat::kCsv);
  Parse(text, mvkp::TargetListFormat::kJson);
  return 0;
}
