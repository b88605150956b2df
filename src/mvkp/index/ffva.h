// FFVA: exact nearest-neighbour search by vector approximation (SPEC §6,
// thesis ch. 5), with a kd partition on top so that large databases are not
// scanned in full.
//
// Layout. The vectors are split recursively at the median of their widest
// dimension into leaves of at most `leaf_size` vectors (a kd-tree). Inside a
// leaf, every vector is approximated by a 4-bit cell code per dimension; the
// 16 cells of dimension j are chosen from the data (equal-count partition of
// that dimension, so partition lengths differ per dimension and per cell).
// Codes are stored two per byte, 32 vectors per block, dimension-major, so
// that the filter is one byte shuffle per dimension for 32 vectors (AVX2
// pshufb, with a scalar reference).
//
// Search. Per query, a 16-entry table per dimension holds the squared gap
// between the query and each cell, quantised *down* to a byte. Leaves are
// visited nearest first; a leaf is skipped when its bounding box is farther
// than the current k-th distance; inside a leaf, a vector's exact distance is
// computed only when the sum of its table entries (a valid lower bound of its
// squared distance, SPEC §6 correction) does not exceed the current k-th
// distance. Results therefore equal brute force (ties by smaller id).
//
// kApprox replaces the lower bound by the thesis's corner-to-corner block
// distance (sum over dimensions of |corner(v) - corner(q)|, compared with the
// squared k-th distance), which is *not* a bound: it may miss neighbours, and
// is kept to measure what the text's version gives up (thesis Table 5.2).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "mvkp/index/knn_index.h"

namespace mvkp {

struct FfvaOptions {
  enum class Filter { kExact, kApprox };
  Filter filter = Filter::kExact;
  // Vectors per kd leaf: a multiple of 32 in [32, 4096]. Smaller leaves prune
  // more finely and cost more bounding-box tests.
  int leaf_size = 64;
  // Subtrees of at most this many blocks of 32 vectors are filtered in one
  // pass instead of leaf by leaf (fewer bounding-box tests and calls).
  int scan_blocks = 8;
};

std::unique_ptr<KnnIndex> MakeFfvaIndex(const FfvaOptions& options = {});

// Index files (FFVA only). Layout, little-endian, every section 64-byte aligned
// so that a loaded index points into the mapped file instead of copying it:
//   "MVKPFFVA" magic, u32 version, u32 header bytes, header fields (sizes,
//   options, section offsets), u32 CRC-32 of the header, then the sections
//   (cell edges, tree nodes, leaf boxes, codes, vectors, ids, labels) and a
//   u32 CRC-32 over all sections.
// Save writes to a temporary file and renames it, so an interrupted save never
// replaces a good index with a partial one.
void SaveIndex(const KnnIndex& index, const std::string& path);

struct IndexLoadOptions {
  bool mmap = true;             // map the file read-only instead of reading it
  bool verify_checksum = true;  // CRC over all sections (reads every page once)
};

// Throws Error(kIo) for unreadable files and Error(kBadIndex) for files that are
// not mvkp indexes, truncated, of a newer version, or corrupt (checksum or
// structure: every offset, count and id is checked before use).
std::unique_ptr<KnnIndex> LoadIndex(const std::string& path, const IndexLoadOptions& options = {});

// Index kinds by name, for options and the CLI: "brute", "exact" (FFVA) and
// "approx" (FFVA with the thesis's block distance). Throws kInvalidArgument.
std::unique_ptr<KnnIndex> MakeIndexByName(const std::string& mode);

}  // namespace mvkp
