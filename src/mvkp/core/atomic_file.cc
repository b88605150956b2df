#include "mvkp/core/atomic_file.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
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

}  // namespace mvkp
