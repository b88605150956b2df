// The index loaders (mvkp/index/): LoadIndex (FFVA files) and ReadFvecs on
// arbitrary bytes, written to a scratch file (both read paths). Each must
// return something usable or throw mvkp::Error.
//
//  - LoadIndex runs on the raw input, then on the input with its file size
//    and both CRC-32s set to match, so the fuzzer gets past the checksums to
//    the structural checks (with and without verify_checksum); a loaded
//    index is then searched.
//  - A vector set ReadFvecs accepts is indexed by FFVA (exact) and brute
//    force, which must agree; the FFVA index is saved and loaded back and
//    must answer the same.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/fvecs.h"
#include "mvkp/index/knn_index.h"
#include "temp_file.h"

namespace {

using mvkp::Neighbor;

// FFVA header (ffva.h): magic[8], u32 version, u32 header bytes, u64 file
// bytes @16, ..., u32 payload CRC @144, u32 header CRC @148 (over bytes
// [0, 148)); sections start at byte 256.
constexpr std::size_t kFileBytesAt = 16, kPayloadCrcAt = 144, kHeaderCrcAt = 148, kHeaderBytes = 256;

mvkp::fuzz::TempFile& File() {
  static mvkp::fuzz::TempFile f(".idx");
  return f;
}

// k nearest of a query: ids in range, distances ascending and not NaN.
void CheckResults(const Neighbor* out, int k, std::size_t n) {
  for (int i = 0; i < k; ++i) {
    if (std::size_t(i) < n && (out[i].id < 0 || std::size_t(out[i].id) >= n || std::isnan(out[i].distance)))
      std::abort();
    if (i && out[i].id >= 0 && !(out[i].distance >= out[i - 1].distance)) std::abort();
  }
}

// Searches a loaded index; with `check`, also its results (only when the
// vectors were checked too: without the checksum they may hold NaN).
void SearchLoaded(const mvkp::KnnIndex& index, bool check) {
  const int dim = index.dim();
  if (dim < 1 || dim > 4096 || index.size() == 0) return;
  std::vector<float> q(std::size_t(dim), 0.f);
  Neighbor out[4], two[2];
  for (float v : {0.f, 1.f, -1000.f}) {
    std::fill(q.begin(), q.end(), v);
    index.Search(q.data(), 4, out);
    if (check) CheckResults(out, 4, index.size());
    index.SearchTwoDistinct(q.data(), two, 0.8f);
  }
}

void LoadFfva(const std::string& path, bool mmap, bool verify) {
  mvkp::IndexLoadOptions o;
  o.mmap = mmap;
  o.verify_checksum = verify;
  std::unique_ptr<mvkp::KnnIndex> index;
  try {
    index = mvkp::LoadIndex(path, o);
  } catch (const mvkp::Error&) {
    return;
  }
  SearchLoaded(*index, verify);
}

// Exact FFVA against brute force on the vectors of an .fvecs file.
void CompareIndexes(const mvkp::VectorSet& v) {
  if (v.n == 0 || v.n > 2048 || v.dim > 64) return;
  for (float x : v.data)
    if (std::fabs(x) > 1e4f) return;  // keep squared distances far from float overflow
  std::vector<std::int32_t> labels(v.n);
  for (std::size_t i = 0; i < v.n; ++i) labels[i] = std::int32_t(i % 3);
  mvkp::FfvaOptions fo;
  fo.leaf_size = 32;
  fo.scan_blocks = 1;
  auto ffva = mvkp::MakeFfvaIndex(fo);
  auto brute = mvkp::MakeBruteForceIndex();
  ffva->Build(v.data.data(), v.n, v.dim, labels.data());
  brute->Build(v.data.data(), v.n, v.dim, labels.data());
  mvkp::SaveIndex(*ffva, File().path());
  const auto loaded = mvkp::LoadIndex(File().path());
  constexpr int k = 3;
  Neighbor a[k], b[k], c[k];
  for (std::size_t i = 0; i < std::min<std::size_t>(v.n, 8); ++i) {
    const float* q = v.data.data() + i * std::size_t(v.dim);
    ffva->Search(q, k, a);
    brute->Search(q, k, b);
    loaded->Search(q, k, c);
    CheckResults(a, k, v.n);
    for (int j = 0; j < k; ++j) {
      // Same distances rank by rank (a missed neighbour shows as a larger one).
      const float tol = 1e-4f * std::max(1.f, b[j].distance);
      if (a[j].id != c[j].id || a[j].distance != c[j].distance) std::abort();
      if ((a[j].id < 0) != (b[j].id < 0) || (b[j].id >= 0 && std::fabs(a[j].distance - b[j].distance) > tol))
        std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool mmap = size % 2;
  const std::string& path = File().Write(data, size);
  LoadFfva(path, mmap, true);

  mvkp::VectorSet v;
  bool vectors = true;
  try {
    v = mvkp::ReadFvecs(path, size % 3 == 0 ? 0 : 4);
  } catch (const mvkp::Error&) {
    vectors = false;
  }
  if (vectors) {
    if (v.dim < 1 || v.data.size() != v.n * std::size_t(v.dim)) std::abort();
    for (float x : v.data)
      if (!std::isfinite(x)) std::abort();
    CompareIndexes(v);  // overwrites the scratch file
  }

  if (size >= kHeaderBytes) {
    std::vector<std::uint8_t> fixed(data, data + size);
    const std::uint64_t bytes = size;
    std::memcpy(fixed.data() + kFileBytesAt, &bytes, 8);
    const std::uint32_t payload_crc = mvkp::Crc32(fixed.data() + kHeaderBytes, size - kHeaderBytes);
    std::memcpy(fixed.data() + kPayloadCrcAt, &payload_crc, 4);
    const std::uint32_t header_crc = mvkp::Crc32(fixed.data(), kHeaderCrcAt);
    std::memcpy(fixed.data() + kHeaderCrcAt, &header_crc, 4);
    // Without the checksum, the structural checks alone must keep the search safe.
    LoadFfva(File().Write(fixed.data(), fixed.size()), !mmap, size % 4 < 2);
  }
  return 0;
}
