#include "mvkp/core/atomic_file.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "mvkp/core/error.h"

namespace mvkp {

void WriteFileAtomically(const std::string& path, const std::function<bool(std::FILE*)>& write) {
  namespace fs = std::filesystem;
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  auto fail = [&](const std::string& what) {
    std::error_code ignore;
    fs::remove(tmp, ignore);
    throw Error(ErrorCode::kIo, path + ": " + what);
  };
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) throw Error(ErrorCode::kIo, path + ": cannot write (temporary file): " + std::strerror(errno));
  bool ok = write(f);
  ok = ok && std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0;
  const int err = errno;
  const bool closed = std::fclose(f) == 0;
  if (!ok || !closed) fail(std::string("write failed: ") + std::strerror(ok ? errno : err));
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) fail("cannot rename temporary file into place: " + ec.message());
}

void WriteFileAtomically(const std::string& path, const void* data, std::size_t size) {
  WriteFileAtomically(path, [&](std::FILE* f) { return size == 0 || std::fwrite(data, 1, size, f) == size; });
}

std::vector<std::uint8_t> ReadFileBytes(const std::string& path, std::uint64_t max_bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error(ErrorCode::kIo, path + ": no such file");
  if (fs::is_directory(path, ec)) throw Error(ErrorCode::kIo, path + ": is a directory");
  const auto size = fs::file_size(path, ec);
  if (ec) throw Error(ErrorCode::kIo, path + ": cannot read file size");
  if (size > max_bytes) throw Error(ErrorCode::kIo, path + ": file too large (" + std::to_string(size) + " bytes)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::kIo, path + ": cannot open for reading");
  std::vector<std::uint8_t> buf(size);
  in.read(reinterpret_cast<char*>(buf.data()), std::streamsize(size));
  if (!in) throw Error(ErrorCode::kIo, path + ": read error");
  return buf;
}

}  // namespace mvkp
