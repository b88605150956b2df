// The archives of `mvkp db export` (mvkp/db/target_archive.h): any bytes are
// either refused as a whole with mvkp::Error, or give entries numbered from 1,
// each a record or the reason it is not one; never a crash.
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "mvkp/core/error.h"
#include "mvkp/db/target_archive.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (std::size_t(1) << 20)) return 0;
  std::vector<mvkp::ArchiveTarget> entries;
  try {
    entries = mvkp::ParseTargetArchive(std::vector<std::uint8_t>(data, data + size), "fuzz");
  } catch (const mvkp::Error&) {
    return 0;
  }
  int n = 0;
  for (const auto& e : entries)
    if (e.entry != ++n) std::abort();
  return 0;
}
