// Target archives: what `mvkp db export DB OUT` writes and `mvkp db import
// NEWDB ARCHIVE` restores into an equal database (same ids, metadata,
// added_at, images, models and model encodings, so the same recognitions).
//
// Format: a POSIX (ustar) tar file, readable with `tar tvf`:
//   targets/000001/image       the encoded target image (JPEG/PNG, may be empty)
//   targets/000001/model       its model (SerializeModel bytes)
//   targets/000001/enc-1       its encodings, in manifest order
//   ...
//   mvkp-archive.json          the manifest, last: {"format": "mvkp-target-archive",
//                              "version": 1, "schema", "exported_at", "targets": [
//                              {id, title, artist, year, url, meta (the stored
//                               JSON text, as a string), width, height,
//                               added_at, "files": {"image": {"name", "bytes",
//                               "crc32"}, "model": {...}}, "encodings": [{"kind",
//                               "name", "bytes", "crc32"}]}]}
// Files are named by entry number, not by id, so any id fits in a tar name.
// Every file's size and CRC-32 are in the manifest: a damaged byte is found.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "mvkp/db/target_store.h"

namespace mvkp {

// Writes every target of the database `db` to the archive `out`, from a
// consistent snapshot (an online backup beside `out`, removed afterwards), so
// a server may keep writing. The file is written atomically (temporary file,
// sync, rename). Throws Error(kIo) if `out` exists and !overwrite, or on a
// read/write error. Returns the number of targets written.
std::size_t ExportTargetArchive(const std::string& db, const std::string& out, bool overwrite = false);

// One target of an archive: its entry number in the manifest (from 1) and
// either the record (info.added_at set, encodings filled) or why it cannot be
// restored (a missing file, a size or CRC-32 mismatch, bad metadata).
struct ArchiveTarget {
  int entry = 0;
  TargetRecord record;
  std::string error;  // empty: record is good
};

// Reads a whole archive into memory. Throws Error(kInvalidArgument) naming
// `path` when the archive as a whole is unusable: not a tar, truncated, a
// damaged tar header, no manifest, a manifest that is not ours or not valid
// JSON; Error(kIo) if it cannot be read. A damaged target is reported in its
// ArchiveTarget, so a caller may restore the others.
std::vector<ArchiveTarget> ReadTargetArchive(const std::string& path);

// The same for an archive's bytes; `name` starts every error message.
std::vector<ArchiveTarget> ParseTargetArchive(const std::vector<std::uint8_t>& bytes, const std::string& name);

// True if `path` names a target archive by its extension (.tar) or content
// (a ustar header), e.g. to tell it from a CSV or JSON list.
bool IsTargetArchive(const std::string& path);

}  // namespace mvkp
