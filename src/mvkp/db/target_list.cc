#include "mvkp/db/target_list.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

#include <nlohmann/json.hpp>

#include "mvkp/core/error.h"
#include "mvkp/db/json_limits.h"

namespace mvkp {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

[[noreturn]] void Bad(const std::string& what) { throw Error(ErrorCode::kInvalidArgument, what); }

// meta must be a JSON object within the metadata limits; `where` names the entry.
void CheckMeta(const std::string& meta, const std::string& where) {
  const Json m = ParseJsonLimited(meta, MetaJsonLimits(), where + ": meta");
  if (!m.is_object()) Bad(where + ": meta must be a JSON object");
}

void CheckCount(std::size_t n, const TargetListLimits& limits, const std::string& name) {
  if (n > limits.max_entries) Bad(name + ": more than " + std::to_string(limits.max_entries) + " targets");
}

std::vector<TargetListEntry> ParseJson(std::string_view text, const std::string& name,
                                       const TargetListLimits& limits, std::vector<int>* rows) {
  JsonLimits jl;
  jl.max_bytes = limits.max_bytes;
  jl.max_depth = 2 + MetaJsonLimits().max_depth;  // the array, an entry, then its meta
  const Json j = ParseJsonLimited(text, jl, name);
  if (j.is_object() && j.contains("targets") && j.contains("database"))
    Bad(name + ": a metadata-only export of an older `mvkp db export` (no images, no models) cannot be "
               "restored; export the database again with `mvkp db export DB OUT.tar` and import that");
  if (!j.is_array()) Bad(name + ": expected a JSON array of targets");
  CheckCount(j.size(), limits, name);
  std::vector<TargetListEntry> out;
  out.reserve(j.size());
  int n = 0;
  for (const Json& o : j) {
    const std::string where = name + ": entry " + std::to_string(++n);
    if (!o.is_object()) Bad(where + ": expected an object with string 'id' and 'image'");
    // An optional string field: absent or null is empty.
    auto str = [&](const char* key, bool required) {
      const auto it = o.find(key);
      if (it == o.end() || it->is_null()) {
        if (required) Bad(where + ": needs string 'id' and 'image'");
        return std::string();
      }
      if (!it->is_string()) Bad(where + ": '" + key + "' must be a string");
      return it->get<std::string>();
    };
    TargetInfo info;
    info.id = str("id", true);
    const std::string image = str("image", true);
    if (info.id.empty() || image.empty()) Bad(where + ": needs a non-empty 'id' and 'image'");
    info.title = str("title", false);
    info.artist = str("artist", false);
    info.url = str("url", false);
    const auto year = o.find("year");
    if (year != o.end() && year->is_number())
      info.year = year->dump();
    else
      info.year = str("year", false);
    const auto meta = o.find("meta");
    if (meta != o.end() && !meta->is_null()) {
      if (!meta->is_object()) Bad(where + ": meta must be a JSON object");
      info.meta = meta->dump();
      CheckMeta(info.meta, where);  // its size and strings, as the store will see them
    }
    out.emplace_back(std::move(info), image);
    if (rows) rows->push_back(n);
  }
  return out;
}

// One CSV line: comma-separated fields, double-quoted ones may hold commas and
// "" for a quote; carriage returns outside quotes are dropped.
std::vector<std::string> SplitCsv(std::string_view line, const std::string& where) {
  std::vector<std::string> f;
  std::string cur;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cur += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      f.push_back(std::move(cur));
      cur.clear();
    } else if (c != '\r') {
      cur += c;
    }
  }
  if (quoted) Bad(where + ": unterminated quoted field (fields cannot span lines)");
  f.push_back(std::move(cur));
  return f;
}

std::vector<TargetListEntry> ParseCsv(std::string_view text, const std::string& name,
                                      const TargetListLimits& limits, std::vector<int>* rows) {
  if (text.size() > limits.max_bytes)
    Bad(name + ": " + std::to_string(text.size()) + " bytes, at most " + std::to_string(limits.max_bytes));
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // a UTF-8 byte order mark (spreadsheets)
  std::vector<TargetListEntry> out;
  std::map<std::string, std::size_t> col;
  int no = 0;
  bool header = true;
  while (!text.empty()) {
    const std::size_t eol = text.find('\n');
    const std::string_view line = text.substr(0, eol);
    text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
    const std::string where = name + ":" + std::to_string(++no);
    if (header) {
      const std::vector<std::string> names = SplitCsv(line, where);
      for (std::size_t i = 0; i < names.size(); ++i) col[names[i]] = i;
      if (!col.count("id") || !col.count("image"))
        Bad(name + ": the header needs 'id' and 'image' columns (optional: title, artist, year, url, meta)");
      header = false;
      continue;
    }
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    const std::vector<std::string> f = SplitCsv(line, where);
    auto get = [&](const char* key) {
      const auto it = col.find(key);
      return it != col.end() && it->second < f.size() ? f[it->second] : std::string();
    };
    TargetInfo info;
    info.id = get("id");
    const std::string image = get("image");
    if (info.id.empty() || image.empty()) Bad(where + ": needs an id and an image");
    info.title = get("title");
    info.artist = get("artist");
    info.year = get("year");
    info.url = get("url");
    const std::string meta = get("meta");
    if (!meta.empty()) {
      CheckMeta(meta, where);
      info.meta = meta;
    }
    CheckCount(out.size() + 1, limits, name);
    out.emplace_back(std::move(info), image);
    if (rows) rows->push_back(no);
  }
  if (header) Bad(name + ": empty list");
  return out;
}

}  // namespace

std::vector<TargetListEntry> ParseTargetList(std::string_view text, TargetListFormat format, const std::string& name,
                                             const TargetListLimits& limits, std::vector<int>* rows) {
  if (rows) rows->clear();
  return format == TargetListFormat::kJson ? ParseJson(text, name, limits, rows) : ParseCsv(text, name, limits, rows);
}

std::vector<TargetListEntry> ReadTargetList(const std::string& path, const TargetListLimits& limits,
                                            std::vector<int>* rows) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".csv" && ext != ".json") Bad(path + ": expected a .csv or .json list");
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  std::ifstream in(path, std::ios::binary);
  Require(!ec && bool(in), ErrorCode::kIo, path + ": cannot open list");
  if (size > limits.max_bytes)
    Bad(path + ": " + std::to_string(size) + " bytes, at most " + std::to_string(limits.max_bytes));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  Require(!in.bad(), ErrorCode::kIo, path + ": cannot read list");
  auto list =
      ParseTargetList(text, ext == ".json" ? TargetListFormat::kJson : TargetListFormat::kCsv, path, limits, rows);
  const fs::path base = fs::path(path).parent_path();
  for (auto& [info, image] : list)
    if (fs::path(image).is_relative()) image = (base / image).string();
  return list;
}

}  // namespace mvkp
