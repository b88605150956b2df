// Target archives (see target_archive.h): a small ustar writer and a strict
// reader. Only what we write is read back: regular files (and directories or
// pax headers a user's `tar` may add); anything else is refused.
#include "mvkp/db/target_archive.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>

#include <nlohmann/json.hpp>

#include "mvkp/core/atomic_file.h"
#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using Bytes = std::vector<std::uint8_t>;

constexpr const char* kFormat = "mvkp-target-archive";
constexpr int kVersion = 1;
constexpr const char* kManifest = "mvkp-archive.json";
constexpr std::size_t kBlock = 512;

std::string Hex32(std::uint32_t v) {
  char b[9];
  std::snprintf(b, sizeof b, "%08x", v);
  return b;
}

// --- writing -----------------------------------------------------------------

// width - 1 octal digits (the caller's values fit) and a NUL.
void Octal(char* field, std::size_t width, std::uint64_t v) {
  field[width - 1] = '\0';
  for (std::size_t i = width - 1; i-- > 0; v >>= 3) field[i] = char('0' + (v & 7));
}

bool WriteEntry(std::FILE* f, const std::string& name, const void* data, std::size_t size, std::int64_t mtime) {
  char h[kBlock] = {};
  std::memcpy(h, name.data(), std::min<std::size_t>(name.size(), 100));
  Octal(h + 100, 8, 0644);
  Octal(h + 108, 8, 0);
  Octal(h + 116, 8, 0);
  Octal(h + 124, 12, size);
  Octal(h + 136, 12, std::uint64_t(std::max<std::int64_t>(mtime, 0)));
  h[156] = '0';
  std::memcpy(h + 257, "ustar", 6);
  std::memcpy(h + 263, "00", 2);
  std::memset(h + 148, ' ', 8);
  unsigned sum = 0;
  for (unsigned char c : h) sum += c;
  Octal(h + 148, 7, sum);  // six digits, NUL, then a space
  h[155] = ' ';
  static const char kZero[kBlock] = {};
  const std::size_t pad = (kBlock - size % kBlock) % kBlock;
  return std::fwrite(h, 1, kBlock, f) == kBlock && (size == 0 || std::fwrite(data, 1, size, f) == size) &&
         std::fwrite(kZero, 1, pad, f) == pad;
}

Json FileJson(const std::string& name, const Bytes& b) {
  return {{"name", name}, {"bytes", b.size()}, {"crc32", Hex32(Crc32(b.data(), b.size()))}};
}

// Removes the snapshot database (and its journals) when done.
struct Snapshot {
  std::string path;
  ~Snapshot() {
    std::error_code ec;
    for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(path + suffix, ec);
  }
};

// --- reading -----------------------------------------------------------------

[[noreturn]] void Bad(const std::string& path, const std::string& what) {
  throw Error(ErrorCode::kInvalidArgument, path + ": not a usable target archive: " + what);
}

std::uint64_t ParseOctal(const char* p, std::size_t width, const std::string& path, const std::string& what) {
  if (static_cast<unsigned char>(p[0]) & 0x80) Bad(path, what + " is too large");
  std::uint64_t v = 0;
  std::size_t i = 0;
  while (i < width && p[i] == ' ') ++i;
  bool digits = false;
  for (; i < width && p[i] >= '0' && p[i] <= '7'; ++i) {
    if (v >> 60) Bad(path, what + " is too large");
    v = v * 8 + std::uint64_t(p[i] - '0');
    digits = true;
  }
  for (; i < width; ++i)
    if (p[i] != ' ' && p[i] != '\0') Bad(path, what + " is not an octal number");
  if (!digits) Bad(path, what + " is empty");
  return v;
}

std::string Field(const char* p, std::size_t width) { return std::string(p, strnlen(p, width)); }

}  // namespace

std::size_t ExportTargetArchive(const std::string& db, const std::string& out, bool overwrite) {
  std::error_code ec;
  if (fs::exists(out, ec)) {
    Require(!fs::equivalent(db, out, ec), ErrorCode::kIo, out + ": export: the output is the database itself");
    Require(overwrite, ErrorCode::kIo, out + ": export: already exists (give --force to replace it)");
  }
  Snapshot snap;
  snap.path = out + ".snapshot-" + std::to_string(::getpid()) + ".db";
  BackupTargetStore(db, snap.path);
  const TargetStore store = TargetStore::Open(snap.path);
  const std::string now = NowUtcIso8601();
  Json targets = Json::array();
  std::size_t n = 0;
  WriteFileAtomically(out, [&](std::FILE* f) {
    const std::int64_t mtime = std::int64_t(std::time(nullptr));
    for (const TargetInfo& info : store.List()) {
      const TargetRecord r = store.Get(info.id, /*with_image=*/true);
      char dir[32];
      std::snprintf(dir, sizeof dir, "targets/%06zu/", ++n);
      const std::string d = dir;
      // meta as the stored text, byte for byte (a restore gives the same row).
      const std::string& meta = info.meta;
      Json t = {{"id", info.id},         {"title", info.title},   {"artist", info.artist}, {"year", info.year},
                {"url", info.url},       {"meta", meta},          {"width", info.width},   {"height", info.height},
                {"added_at", info.added_at}};
      t["files"] = {{"image", FileJson(d + "image", r.image)}, {"model", FileJson(d + "model", r.model)}};
      if (!WriteEntry(f, d + "image", r.image.data(), r.image.size(), mtime) ||
          !WriteEntry(f, d + "model", r.model.data(), r.model.size(), mtime))
        return false;
      Json enc = Json::array();
      int k = 0;
      for (const auto& [kind, data] : store.Encodings(info.id)) {
        const std::string name = d + "enc-" + std::to_string(++k);
        Json e = FileJson(name, data);
        e["kind"] = kind;
        enc.push_back(e);
        if (!WriteEntry(f, name, data.data(), data.size(), mtime)) return false;
      }
      t["encodings"] = enc;
      targets.push_back(std::move(t));
    }
    const std::string manifest =
        Json{{"format", kFormat}, {"version", kVersion}, {"schema", store.schema_version()}, {"exported_at", now},
             {"targets", targets}}
            .dump(1) +
        "\n";
    static const char kZero[2 * kBlock] = {};
    return WriteEntry(f, kManifest, manifest.data(), manifest.size(), mtime) &&
           std::fwrite(kZero, 1, sizeof kZero, f) == sizeof kZero;
  });
  return n;
}

bool IsTargetArchive(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext == ".tar") return true;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return false;
  char h[kBlock];
  const bool whole = std::fread(h, 1, kBlock, f) == kBlock;
  std::fclose(f);
  return whole && std::memcmp(h + 257, "ustar", 5) == 0;
}

std::vector<ArchiveTarget> ReadTargetArchive(const std::string& path) {
  return ParseTargetArchive(ReadFileBytes(path, std::uint64_t(1) << 40), path);
}

std::vector<ArchiveTarget> ParseTargetArchive(const Bytes& file, const std::string& path) {
  std::map<std::string, Bytes> files;
  std::size_t pos = 0;
  bool ended = false;
  int n = 0;
  while (!ended) {
    if (pos + kBlock > file.size()) Bad(path, file.empty() ? "empty file" : "truncated (no end-of-archive marker)");
    const char* h = reinterpret_cast<const char*>(file.data() + pos);
    if (std::all_of(h, h + kBlock, [](char c) { return c == 0; })) {
      ended = true;
      break;
    }
    const std::string what = "tar entry " + std::to_string(++n);
    unsigned sum = 0;
    for (std::size_t i = 0; i < kBlock; ++i) sum += (i >= 148 && i < 156) ? ' ' : static_cast<unsigned char>(h[i]);
    if (ParseOctal(h + 148, 8, path, what + ": header checksum") != sum || std::memcmp(h + 257, "ustar", 5) != 0)
      Bad(path, what + ": damaged tar header (at byte " + std::to_string(pos) + ")");
    const std::uint64_t size = ParseOctal(h + 124, 12, path, what + ": size");
    pos += kBlock;
    if (size > file.size() - pos) Bad(path, what + ": truncated (" + std::to_string(size) + " bytes announced)");
    const std::string prefix = Field(h + 345, 155), base = Field(h + 0, 100);
    const std::string name = prefix.empty() ? base : prefix + "/" + base;
    const char type = h[156];
    if (type == '0' || type == '\0') {
      if (!files.emplace(name, Bytes(file.begin() + long(pos), file.begin() + long(pos + size))).second)
        Bad(path, what + ": '" + name + "' appears twice");
    } else if (type != '5' && type != 'x' && type != 'g') {
      Bad(path, what + ": '" + name + "' is not a regular file");
    }
    pos += (size + kBlock - 1) / kBlock * kBlock;
  }
  const auto m = files.find(kManifest);
  if (m == files.end()) Bad(path, std::string("no ") + kManifest + " (not made by `mvkp db export`)");
  JsonLimits lim;
  lim.max_bytes = std::size_t(256) << 20;
  lim.max_depth = 4 + MetaJsonLimits().max_depth;  // manifest, targets, a target, files
  // A meta stored before the limits may be long: its entry is refused, not the archive.
  lim.max_string_bytes = lim.max_bytes;
  const Json j = ParseJsonLimited(std::string_view(reinterpret_cast<const char*>(m->second.data()), m->second.size()),
                                  lim, path + ": " + kManifest);
  // Types checked before values: json's value()/get() throw on a wrong type (a
  // number for "format" crashed the fuzzer), and only mvkp::Error may leave here.
  if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
      j["format"].get<std::string>() != kFormat || !j.contains("targets") || !j["targets"].is_array())
    Bad(path, std::string(kManifest) + " is not a target archive manifest");
  if (!j.contains("version") || !j["version"].is_number_integer() || j["version"].get<int>() > kVersion)
    Bad(path, "archive version is newer than this build's " + std::to_string(kVersion));

  std::vector<ArchiveTarget> out;
  int entry = 0;
  for (const Json& t : j["targets"]) {
    ArchiveTarget a;
    a.entry = ++entry;
    try {
      if (!t.is_object()) throw Error(ErrorCode::kInvalidArgument, "not an object");
      auto str = [&](const char* k) {
        if (!t.contains(k) || !t[k].is_string())
          throw Error(ErrorCode::kInvalidArgument, std::string("'") + k + "' must be a string");
        return t[k].get<std::string>();
      };
      auto num = [&](const char* k) {
        if (!t.contains(k) || !t[k].is_number_integer())
          throw Error(ErrorCode::kInvalidArgument, std::string("'") + k + "' must be an integer");
        return t[k].get<int>();
      };
      auto blob = [&](const Json& f) {
        if (!f.is_object() || !f.contains("name") || !f["name"].is_string() || !f.contains("bytes") ||
            !f["bytes"].is_number_unsigned() || !f.contains("crc32") || !f["crc32"].is_string())
          throw Error(ErrorCode::kInvalidArgument, "a file entry needs name, bytes and crc32");
        const std::string name = f["name"];
        const auto it = files.find(name);
        if (it == files.end()) throw Error(ErrorCode::kInvalidArgument, "'" + name + "' is missing from the archive");
        if (it->second.size() != f["bytes"].get<std::uint64_t>() ||
            Hex32(Crc32(it->second.data(), it->second.size())) != f["crc32"].get<std::string>())
          throw Error(ErrorCode::kInvalidArgument, "'" + name + "' is damaged (size or CRC-32 differs)");
        return it->second;
      };
      TargetRecord& r = a.record;
      r.info.id = str("id");
      r.info.title = str("title");
      r.info.artist = str("artist");
      r.info.year = str("year");
      r.info.url = str("url");
      r.info.added_at = str("added_at");
      r.info.width = num("width");
      r.info.height = num("height");
      r.info.meta = str("meta");  // checked as the store checks it, by the caller
      if (!t.contains("files") || !t["files"].is_object() || !t["files"].contains("image") ||
          !t["files"].contains("model"))
        throw Error(ErrorCode::kInvalidArgument, "'files' needs image and model");
      r.image = blob(t["files"]["image"]);
      r.model = blob(t["files"]["model"]);
      if (t.contains("encodings")) {
        if (!t["encodings"].is_array()) throw Error(ErrorCode::kInvalidArgument, "'encodings' must be an array");
        for (const Json& e : t["encodings"]) {
          if (!e.is_object() || !e.contains("kind") || !e["kind"].is_string())
            throw Error(ErrorCode::kInvalidArgument, "an encoding needs a string 'kind'");
          r.encodings.emplace_back(e["kind"].get<std::string>(), blob(e));
        }
      }
    } catch (const Error& e) {
      a.error = e.what();
    } catch (const nlohmann::json::exception& e) {
      a.error = e.what();
    }
    out.push_back(std::move(a));
  }
  return out;
}

}  // namespace mvkp
