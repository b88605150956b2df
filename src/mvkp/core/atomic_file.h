// Saving files so that nothing a user saved is lost: the bytes go to a
// temporary file beside the target, which is flushed, synced and only then
// renamed over it. An interrupted or failed save leaves the old file intact.
#pragma once

#include <cstddef>
#include <cstdio>
#include <functional>
#include <cstdint>
#include <string>
#include <vector>

namespace mvkp {

// `write` fills the open temporary file and returns false on a write error.
// Throws Error(kIo) naming `path` when the file cannot be created, written,
// synced or renamed into place; the temporary file is removed then.
void WriteFileAtomically(const std::string& path, const std::function<bool(std::FILE*)>& write);

// The same for one buffer.
void WriteFileAtomically(const std::string& path, const void* data, std::size_t size);

// The whole file. Throws Error(kIo) naming `path` if it is missing, a
// directory, larger than max_bytes or unreadable.
std::vector<std::uint8_t> ReadFileBytes(const std::string& path, std::uint64_t max_bytes = std::uint64_t(1) << 31);

}  // namespace mvkp
