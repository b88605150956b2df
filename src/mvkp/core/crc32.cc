#include "mvkp/core/crc32.h"

#include <zlib.h>

#include <algorithm>

namespace mvkp {

std::uint32_t Crc32(const void* data, std::size_t size, std::uint32_t crc) {
  // zlib's crc32 takes a uInt length: feed large buffers in pieces.
  const auto* p = static_cast<const Bytef*>(data);
  uLong c = crc;
  while (size > 0) {
    const std::size_t step = std::min<std::size_t>(size, 1u << 30);
    c = crc32(c, p, uInt(step));
    p += step;
    size -= step;
  }
  return std::uint32_t(c);
}

}  // namespace mvkp
