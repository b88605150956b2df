// A scratch file for fuzz targets whose library entry point reads a path:
// one per process, rewritten with each input, removed at exit (not after a
// crash: /dev/shm/mvkp_fuzz_* are then left over).
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace mvkp::fuzz {

class TempFile {
 public:
  // `suffix` matters to readers that look at the extension (".las", ".png").
  // In $TMPDIR, else /dev/shm (memory: an fsync there costs nothing), else /tmp.
  explicit TempFile(const std::string& suffix) {
    const char* dir = std::getenv("TMPDIR");
    const std::string base = dir && *dir ? dir : ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    std::string tmpl = base + "/mvkp_fuzz_XXXXXX" + suffix;
    const int fd = ::mkstemps(tmpl.data(), int(suffix.size()));
    if (fd < 0) std::abort();
    ::close(fd);
    path_ = tmpl;
  }
  ~TempFile() { std::remove(path_.c_str()); }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;

  const std::string& path() const { return path_; }

  // Replaces the file's content with the input; returns its path.
  const std::string& Write(const std::uint8_t* data, std::size_t size) {
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) std::abort();
    return path_;
  }

 private:
  std::string path_;
};

}  // namespace mvkp::fuzz
