// Target lists: the files `mvkp db import` reads to add many targets at once.
//
//   CSV   a header line naming the columns, id and image required, title,
//         artist, year, url and meta optional, in any order; one target per
//         line; fields separated by commas, double-quoted when they hold a
//         comma or a quote ("" inside quotes is a quote); no line breaks
//         inside a field; blank lines are skipped.
//   JSON  an array of objects with the same keys: id and image strings,
//         title, artist, url strings, year a string or a number, meta any
//         JSON object.
//
// A list is parsed before anything is trained, and every entry's meta is
// checked against the metadata limits (MetaJsonLimits) here, so a bad list
// fails at once with the line or entry at fault. A JSON list is parsed with
// ParseJsonLimited: depth and size are refused while parsing, so a list that
// nests a value 300 000 levels deep is an error, not a stack overflow.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "mvkp/db/target_store.h"

namespace mvkp {

enum class TargetListFormat { kCsv, kJson };

// A JSON list may hold this many bytes; its entries nest two levels (the
// array, each object) above their meta, which may nest MetaJsonLimits().
struct TargetListLimits {
  std::size_t max_bytes = std::size_t(64) << 20;  // the whole text, CSV or JSON
  std::size_t max_entries = 100000;                // targets in one list
};

// One entry: the target's metadata (width, height and added_at unset) and its
// image path exactly as the list gives it.
using TargetListEntry = std::pair<TargetInfo, std::string>;

// Parses a list's text. `name` (e.g. the file path) starts every error
// message, which names the line (CSV) or entry (JSON, from 1) at fault.
// Throws Error(kInvalidArgument) for a syntax error, a missing id or image,
// an invalid meta, or a list over the limits. An empty list (a header, or
// []) is valid and gives no entries. A metadata-only export of older `mvkp db
// export` (an object with "targets") is refused with what to do instead.
// `rows`, if given, receives each entry's CSV line or JSON entry number (from
// 1), for messages about one entry later (e.g. its training failed).
std::vector<TargetListEntry> ParseTargetList(std::string_view text, TargetListFormat format,
                                             const std::string& name, const TargetListLimits& limits = {},
                                             std::vector<int>* rows = nullptr);

// Reads a list file, its format by extension (.csv or .json, any case), and
// resolves relative image paths against the list's folder. Throws Error(kIo)
// when it cannot be read, Error(kInvalidArgument) for another extension and
// as ParseTargetList.
std::vector<TargetListEntry> ReadTargetList(const std::string& path, const TargetListLimits& limits = {},
                                            std::vector<int>* rows = nullptr);

}  // namespace mvkp
