#include "mvkp/model/model.h"

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <type_traits>

#include "mvkp/core/atomic_file.h"
#include "mvkp/core/crc32.h"
#include "mvkp/core/error.h"

namespace mvkp {
namespace {

constexpr char kMagic[8] = {'M', 'V', 'K', 'P', 'M', 'O', 'D', 'L'};
constexpr std::size_t kHeaderBytes = 8 + 4 + 8;

class Writer {
 public:
  template <typename T>
  void Put(T v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    buf.insert(buf.end(), p, p + sizeof(T));
  }
  void PutBytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    buf.insert(buf.end(), b, b + n);
  }
  std::vector<std::uint8_t> buf;
};

class Reader {
 public:
  Reader(const std::uint8_t* d, std::size_t n, const std::string& name) : d_(d), n_(n), name_(name) {}
  template <typename T>
  T Get() {
    T v;
    Need(sizeof(T));
    std::memcpy(&v, d_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  void GetBytes(void* out, std::size_t n) {
    Need(n);
    std::memcpy(out, d_ + pos_, n);
    pos_ += n;
  }
  std::size_t remaining() const { return n_ - pos_; }

 private:
  void Need(std::size_t k) {
    if (k > n_ - pos_) throw Error(ErrorCode::kBadModel, name_ + ": corrupt model (payload ends early)");
  }
  const std::uint8_t* d_;
  std::size_t n_, pos_ = 0;
  const std::string& name_;
};

[[noreturn]] void Bad(const std::string& name, const std::string& what) {
  throw Error(ErrorCode::kBadModel, name + ": " + what);
}

}  // namespace

void Model::Validate(const std::string& name) const {
  const int m = descriptors.rows;
  if (params.patch_size < 4 || params.patch_size > 256 || (params.patch_size & (params.patch_size - 1)))
    Bad(name, "invalid patch size " + std::to_string(params.patch_size));
  if (params.dims < 1 || params.dims > params.patch_size * params.patch_size - 1)
    Bad(name, "invalid descriptor dimension " + std::to_string(params.dims) + " for patch size " +
                  std::to_string(params.patch_size));
  if (!(params.smooth_sigma >= 0.f && params.smooth_sigma <= 10.f)) Bad(name, "invalid smoothing sigma");
  if (params.orientation_radius < 2 || params.orientation_radius > 64) Bad(name, "invalid orientation radius");
  if (params.block_size < 2 || params.block_size > 15) Bad(name, "invalid detector block size");
  if (!(params.min_distance >= 0.f && params.min_distance <= 100.f)) Bad(name, "invalid detector spacing");
  if (!(params.relative_threshold >= 0.f && params.relative_threshold < 1.f) || !(params.min_strength >= 0.f))
    Bad(name, "invalid detector threshold");
  if (object_width < 1 || object_height < 1) Bad(name, "invalid object size");
  if (m > 0 && (descriptors.type() != CV_32F || descriptors.cols != params.dims))
    Bad(name, "descriptor matrix does not match the declared dimension");
  if (int(labels.size()) != m) Bad(name, "label count does not match descriptor count");
  for (auto l : labels)
    if (l < 0 || l >= int(locations.size())) Bad(name, "descriptor label out of range");
  if (params.levels < 1 || params.levels > 16) Bad(name, "invalid number of pyramid levels " + std::to_string(params.levels));
  for (const auto& loc : locations) {
    if (!std::isfinite(loc.x) || !std::isfinite(loc.y)) Bad(name, "non-finite location");
    if (loc.level < 0 || loc.level >= params.levels) Bad(name, "location level out of range");
    if (!(loc.scale > 0.f && loc.scale < 1e4f)) Bad(name, "invalid location scale");
  }
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < descriptors.cols; ++j)
      if (!std::isfinite(descriptors.at<float>(i, j))) Bad(name, "non-finite descriptor value");
}

std::vector<std::uint8_t> SerializeModel(const Model& model) {
  model.Validate("model");
  Writer p;
  const ModelParams& q = model.params;
  p.Put(q.smooth_sigma);
  p.Put<std::int32_t>(q.patch_size);
  p.Put<std::int32_t>(q.dims);
  p.Put<std::uint8_t>(q.orient ? 1 : 0);
  p.Put<std::int32_t>(q.orientation_radius);
  p.Put(q.min_strength);
  p.Put(q.relative_threshold);
  p.Put(q.min_distance);
  p.Put<std::int32_t>(q.block_size);
  p.Put<std::int32_t>(q.views);
  p.Put<std::int32_t>(q.locations);
  p.Put<std::int32_t>(q.clusters);
  p.Put<std::uint64_t>(q.seed);
  p.Put(q.min_scale);
  p.Put(q.max_scale);
  p.Put(q.train_ms);
  p.Put<std::uint8_t>(q.view_model);
  p.Put<std::int32_t>(q.levels);
  p.Put(q.max_tilt_deg);
  p.Put(q.level_min_scale);
  p.Put(q.level_max_scale);
  p.Put<std::int32_t>(model.object_width);
  p.Put<std::int32_t>(model.object_height);
  p.Put<std::uint32_t>(std::uint32_t(model.locations.size()));
  for (const auto& l : model.locations) {
    p.Put(l.x);
    p.Put(l.y);
    p.Put<std::int32_t>(l.stability);
    p.Put<std::uint8_t>(std::uint8_t(l.level));
    p.Put(l.scale);
  }
  const std::uint32_t m = std::uint32_t(model.descriptors.rows);
  p.Put(m);
  for (std::uint32_t i = 0; i < m; ++i) {
    p.Put<std::int32_t>(model.labels[i]);
    p.PutBytes(model.descriptors.ptr<float>(int(i)), sizeof(float) * std::size_t(q.dims));
  }

  Writer f;
  f.PutBytes(kMagic, 8);
  f.Put<std::uint32_t>(kModelFormatVersion);
  f.Put<std::uint64_t>(p.buf.size());
  f.PutBytes(p.buf.data(), p.buf.size());
  f.Put<std::uint32_t>(Crc32(p.buf.data(), p.buf.size()));
  return f.buf;
}

Model DeserializeModel(const std::uint8_t* data, std::size_t size, const std::string& name) {
  if (size < 8 || std::memcmp(data, kMagic, 8) != 0) Bad(name, "not an mvkp model file (bad magic)");
  if (size < kHeaderBytes) Bad(name, "truncated model file (header incomplete)");
  std::uint32_t version;
  std::uint64_t payload;
  std::memcpy(&version, data + 8, 4);
  std::memcpy(&payload, data + 12, 8);
  if (version == 0) Bad(name, "corrupt model (format version 0)");
  if (version > kModelFormatVersion)
    Bad(name, "model format version " + std::to_string(version) + " is newer than this mvkp reads (versions 1.." +
                  std::to_string(kModelFormatVersion) + "); upgrade mvkp or retrain");
  if (payload > size - kHeaderBytes || size - kHeaderBytes - payload < 4)
    Bad(name, "truncated model file (" + std::to_string(size) + " bytes; header declares a " +
                  std::to_string(payload) + "-byte payload)");
  if (size - kHeaderBytes - payload > 4) Bad(name, "corrupt model (trailing bytes after the checksum)");
  const std::uint8_t* pl = data + kHeaderBytes;
  std::uint32_t crc;
  std::memcpy(&crc, pl + payload, 4);
  if (Crc32(pl, payload) != crc) Bad(name, "corrupt model (checksum mismatch)");

  Reader r(pl, payload, name);
  Model model;
  ModelParams& q = model.params;
  q.smooth_sigma = r.Get<float>();
  q.patch_size = r.Get<std::int32_t>();
  q.dims = r.Get<std::int32_t>();
  q.orient = r.Get<std::uint8_t>() != 0;
  q.orientation_radius = r.Get<std::int32_t>();
  q.min_strength = r.Get<float>();
  q.relative_threshold = r.Get<float>();
  q.min_distance = r.Get<float>();
  q.block_size = r.Get<std::int32_t>();
  q.views = r.Get<std::int32_t>();
  q.locations = r.Get<std::int32_t>();
  q.clusters = r.Get<std::int32_t>();
  q.seed = r.Get<std::uint64_t>();
  q.min_scale = r.Get<float>();
  q.max_scale = r.Get<float>();
  q.train_ms = r.Get<double>();
  if (version >= 2) {
    q.view_model = r.Get<std::uint8_t>();
    q.levels = r.Get<std::int32_t>();
    q.max_tilt_deg = r.Get<float>();
    q.level_min_scale = r.Get<float>();
    q.level_max_scale = r.Get<float>();
    if (q.view_model > 2) Bad(name, "corrupt model (unknown view model " + std::to_string(q.view_model) + ")");
    if (q.levels < 1 || q.levels > 16) Bad(name, "corrupt model (" + std::to_string(q.levels) + " pyramid levels)");
  }
  model.object_width = r.Get<std::int32_t>();
  model.object_height = r.Get<std::int32_t>();
  if (q.dims < 1 || q.dims > 4096) Bad(name, "invalid descriptor dimension " + std::to_string(q.dims));
  const std::uint32_t nl = r.Get<std::uint32_t>();
  const std::uint64_t loc_bytes = version >= 2 ? 17 : 12;
  if (std::uint64_t(nl) * loc_bytes > r.remaining()) Bad(name, "corrupt model (location count exceeds the payload)");
  model.locations.resize(nl);
  for (auto& l : model.locations) {
    l.x = r.Get<float>();
    l.y = r.Get<float>();
    l.stability = r.Get<std::int32_t>();
    if (version >= 2) {
      l.level = r.Get<std::uint8_t>();
      l.scale = r.Get<float>();
    }
  }
  const std::uint32_t m = r.Get<std::uint32_t>();
  const std::uint64_t row = 4 + 4ull * std::uint64_t(q.dims);
  if (std::uint64_t(m) * row != r.remaining()) Bad(name, "corrupt model (descriptor block has the wrong size)");
  model.descriptors.create(int(m), q.dims, CV_32F);
  model.labels.resize(m);
  for (std::uint32_t i = 0; i < m; ++i) {
    model.labels[i] = r.Get<std::int32_t>();
    r.GetBytes(model.descriptors.ptr<float>(int(i)), sizeof(float) * std::size_t(q.dims));
  }
  model.Validate(name);
  return model;
}

void SaveModel(const Model& model, const std::string& path) {
  const auto bytes = SerializeModel(model);
  WriteFileAtomically(path, bytes.data(), bytes.size());
}

Model LoadModel(const std::string& path) {
  const std::vector<std::uint8_t> buf = ReadFileBytes(path);
  return DeserializeModel(buf.data(), buf.size(), path);
}

}  // namespace mvkp
