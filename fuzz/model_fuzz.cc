// The model loader (mvkp/model/model.h): DeserializeModel on arbitrary bytes
// must return a valid model or throw mvkp::Error. Random bytes rarely carry a
// right payload size and CRC-32, so each input is also tried with those two
// fields set to match (the rest of the input untouched), which lets the
// fuzzer reach every check inside the payload. A model that loads must
// serialize, and load again to the same bytes.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/model/model.h"

namespace {

// File layout (model.h): magic[8], u32 version, u64 payload_bytes, payload, u32 crc.
constexpr std::size_t kHeader = 8 + 4 + 8;

void Load(const std::uint8_t* data, std::size_t size) {
  mvkp::Model m;
  try {
    m = mvkp::DeserializeModel(data, size, "fuzz");
  } catch (const mvkp::Error&) {
    return;
  }
  // Loaded, so valid: the round trip may not fail.
  const std::vector<std::uint8_t> a = mvkp::SerializeModel(m);
  const std::vector<std::uint8_t> b = mvkp::SerializeModel(mvkp::DeserializeModel(a.data(), a.size(), "again"));
  if (a != b) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Load(data, size);
  if (size >= kHeader + 4) {
    std::vector<std::uint8_t> fixed(data, data + size);
    const std::uint64_t payload = size - kHeader - 4;
    std::memcpy(fixed.data() + 12, &payload, 8);
    const std::uint32_t crc = mvkp::Crc32(fixed.data() + kHeader, payload);
    std::memcpy(fixed.data() + kHeader + payload, &crc, 4);
    Load(fixed.data(), fixed.size());
  }
  return 0;
}
