// IEEE CRC-32 (the zlib/PNG polynomial), as used by mvkp's file formats.
#pragma once

#include <cstddef>
#include <cstdint>

namespace mvkp {

// CRC-32 of `size` bytes; `crc` continues a previous value (0 to start).
std::uint32_t Crc32(const void* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace mvkp
