// mvkp knn: k nearest neighbours of .fvecs queries in an .fvecs database or a
// saved FFVA index, with build/search timings, memory and distance counts; and
// --dump-descriptors, which writes the WH descriptors of images as .fvecs.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/describe/features.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/fvecs.h"
#include "mvkp/index/knn_index.h"
#include "output.h"

namespace mvkp::cli {
namespace {

struct KnnArgs {
  std::string db, queries;
  int k = 0;
  std::string mode = "exact";
  bool json = false;
  bool batch = false;
  bool no_verify = false;
  std::string save_index;
  std::vector<std::string> dump_images;
  std::string output;
  int max_per_image = 0;
  // Set by Register: which options were given on the command line.
  const CLI::Option *k_opt = nullptr, *mode_opt = nullptr, *json_opt = nullptr, *batch_opt = nullptr,
                    *verify_opt = nullptr, *save_opt = nullptr, *dump_opt = nullptr, *out_opt = nullptr,
                    *max_opt = nullptr;
};

// Options that belong to the other form of the command are errors, not silently ignored.
void RejectGiven(const std::vector<const CLI::Option*>& options, const std::string& why) {
  for (const CLI::Option* o : options)
    Require(o->count() == 0, ErrorCode::kInvalidArgument, o->get_name() + " " + why);
}

// Index files start with this magic; anything else is read as .fvecs.
bool IsIndexFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  return in.read(magic, sizeof magic) && std::memcmp(magic, "MVKPFFVA", sizeof magic) == 0;
}

// "ffva" -> "exact", "ffva-approx" -> "approx", "brute" -> "brute".
std::string ModeOfIndex(const KnnIndex& index) {
  const std::string n = index.name();
  if (n == "ffva") return "exact";
  if (n == "ffva-approx") return "approx";
  return n;
}

// Runs f; an invalid-argument error from the index (NaN/inf values) is
// rethrown naming the file whose vectors caused it.
template <class F>
void NamingFile(const std::string& path, F&& f) {
  try {
    f();
  } catch (const Error& e) {
    if (e.code() == ErrorCode::kInvalidArgument) throw Error(e.code(), path + ": " + e.what());
    throw;
  }
}

int RunDump(const KnnArgs& a) {
  Require(!a.output.empty(), ErrorCode::kInvalidArgument, "--dump-descriptors needs -o OUT.fvecs");
  Require(a.max_per_image >= 0, ErrorCode::kInvalidArgument, "--max-per-image must be >= 0 (0: no limit)");
  const FeatureOptions options;  // the defaults the product (and bench/datasets.cc) use
  const int dim = options.describer.dims;
  std::vector<float> all;
  std::vector<std::string> none;  // images without descriptors
  for (const std::string& path : a.dump_images) {
    const cv::Mat gray = LoadImageGray(path);
    const cv::Mat desc = ExtractFeatures(gray, options).descriptors;
    std::size_t rows = desc.empty() ? 0 : std::size_t(desc.rows);
    if (a.max_per_image > 0 && rows > std::size_t(a.max_per_image)) rows = std::size_t(a.max_per_image);
    if (rows == 0) {
      none.push_back(path);
      continue;
    }
    CV_Assert(desc.type() == CV_32F && desc.isContinuous() && desc.cols == dim);
    all.insert(all.end(), desc.ptr<float>(), desc.ptr<float>() + rows * std::size_t(dim));
  }
  const std::size_t images = a.dump_images.size();
  Require(!all.empty(), ErrorCode::kInvalidArgument,
          (images == 1 ? a.dump_images[0] + ": no descriptors (no keypoints found)"
                       : "no descriptors in any of the " + std::to_string(images) + " images (no keypoints found)") +
              "; " + a.output + " not written");
  for (const std::string& path : none)
    std::fprintf(stderr, "mvkp knn: %s: no descriptors (no keypoints found)\n", path.c_str());
  const std::size_t m = all.size() / std::size_t(dim);
  WriteFvecs(a.output, all.data(), m, dim);
  std::printf("wrote %zu descriptors (dim %d) from %zu image%s to %s", m, dim, images, images == 1 ? "" : "s",
              a.output.c_str());
  if (!none.empty()) std::printf(" (%zu with no descriptors)", none.size());
  std::printf("\n");
  return 0;
}

int RunKnn(const KnnArgs& a) {
  Require(a.k_opt->count() > 0, ErrorCode::kInvalidArgument, "missing --k (neighbours per query)");
  Require(a.k >= 1, ErrorCode::kInvalidArgument, "--k must be >= 1 (got " + std::to_string(a.k) + ")");
  Require(a.mode == "exact" || a.mode == "approx" || a.mode == "brute", ErrorCode::kInvalidArgument,
          "unknown --mode '" + a.mode + "' (expected exact, approx or brute)");
  Require(a.save_index.empty() || a.mode != "brute", ErrorCode::kInvalidArgument,
          "--save-index needs --mode exact or approx");

  for (const std::string* input : {&a.db, &a.queries}) {
    std::error_code ec;
    Require(a.save_index.empty() || (a.save_index != *input && !std::filesystem::equivalent(a.save_index, *input, ec)),
            ErrorCode::kInvalidArgument, "--save-index " + a.save_index + " would overwrite an input file");
  }

  // Database: a saved index (by its magic) or .fvecs vectors to build one from.
  const bool loaded = IsIndexFile(a.db);
  std::unique_ptr<KnnIndex> index;
  VectorSet db;
  double setup_ms = 0;
  std::string mode = a.mode;
  if (loaded) {
    IndexLoadOptions lo;
    lo.mmap = true;
    lo.verify_checksum = !a.no_verify;
    Timer t;
    index = LoadIndex(a.db, lo);
    setup_ms = t.ElapsedMs();
    mode = ModeOfIndex(*index);
    Require(a.mode_opt->count() == 0 || a.mode == mode, ErrorCode::kInvalidArgument,
            a.db + ": is a saved '" + mode + "' index; --mode " + a.mode + " does not apply (omit --mode)");
    Require(index->size() > 0, ErrorCode::kBadIndex, a.db + ": index holds no vectors");
  } else {
    db = ReadFvecs(a.db);  // throws for missing, empty, truncated, malformed and non-finite files
    Require(db.n > 0, ErrorCode::kInvalidArgument, a.db + ": empty database (no vectors)");
  }
  const std::size_t n = loaded ? index->size() : db.n;
  const int dim = loaded ? index->dim() : db.dim;
  Require(std::size_t(a.k) <= n, ErrorCode::kInvalidArgument,
          "--k " + std::to_string(a.k) + " is larger than the database (" + std::to_string(n) + " vector" +
              (n == 1 ? "" : "s") + ")");

  const VectorSet q = ReadFvecs(a.queries);
  Require(q.n > 0, ErrorCode::kInvalidArgument, a.queries + ": empty query file (no vectors)");
  Require(q.dim == dim, ErrorCode::kInvalidArgument,
          "dimension mismatch: DB has " + std::to_string(dim) + ", queries have " + std::to_string(q.dim) + " (" +
              a.db + ", " + a.queries + ")");

  if (!loaded) {
    index = MakeIndexByName(a.mode);
    Timer t;
    NamingFile(a.db, [&] { index->Build(db.data.data(), db.n, db.dim, nullptr); });
    setup_ms = t.ElapsedMs();
    db = VectorSet{};  // the index holds its own copy
  }
  if (!a.save_index.empty()) SaveIndex(*index, a.save_index);

  const std::size_t nq = q.n, k = std::size_t(a.k);
  std::vector<Neighbor> out(nq * k);
  std::vector<double> per_query_us;
  index->ResetStats();
  double search_ms = 0;
  NamingFile(a.queries, [&] {
    if (a.batch) {
      Timer t;
      index->SearchBatch(q.data.data(), nq, a.k, out.data());
      search_ms = t.ElapsedMs();
    } else {
      per_query_us.reserve(nq);
      Timer total;
      for (std::size_t i = 0; i < nq; ++i) {
        Timer t;
        index->Search(q.data.data() + i * std::size_t(dim), a.k, out.data() + i * k);
        per_query_us.push_back(t.ElapsedMs() * 1000);
      }
      search_ms = total.ElapsedMs();
    }
  });
  const double computations = double(index->distance_computations()) / double(nq);
  const double bytes_per_vector = double(index->memory_bytes()) / double(n);
  const double raw_bytes_per_vector = 4.0 * dim;
  const double us_per_query = search_ms * 1000 / double(nq);

  if (a.json) {
    nlohmann::ordered_json neighbors = nlohmann::ordered_json::array(), distances = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < nq; ++i) {
      nlohmann::ordered_json ids = nlohmann::ordered_json::array(), ds = nlohmann::ordered_json::array();
      for (std::size_t j = 0; j < k; ++j) {
        ids.push_back(out[i * k + j].id);
        ds.push_back(double(out[i * k + j].distance));
      }
      neighbors.push_back(std::move(ids));
      distances.push_back(std::move(ds));
    }
    nlohmann::ordered_json j = {{"db", a.db}, {"queries", a.queries}, {"n", n}, {"dim", dim}, {"nq", nq}, {"k", a.k},
                        {"mode", mode}, {"metric", "squared_l2"}, {"batch", a.batch}};
    j[loaded ? "load_ms" : "build_ms"] = setup_ms;
    j["search_ms"] = search_ms;
    j["us_per_query"] = us_per_query;
    if (!a.batch) j["median_us_per_query"] = Median(per_query_us);
    j["distance_computations_per_query"] = computations;
    j["bytes_per_vector"] = bytes_per_vector;
    j["raw_bytes_per_vector"] = raw_bytes_per_vector;
    if (!a.save_index.empty()) j["saved_index"] = a.save_index;
    j["neighbors"] = std::move(neighbors);
    j["distances"] = std::move(distances);
    std::cout << j.dump() << std::endl;
    return 0;
  }
  const std::string kind = mode == "brute" ? "brute force" : mode + " (" + index->name() + ")";
  std::printf("mvkp knn: %s, k=%d, squared L2\n", kind.c_str(), a.k);
  std::printf("  database      %zu vectors x %d dims  (%s%s)\n", n, dim, a.db.c_str(), loaded ? ", saved index" : "");
  if (loaded)
    std::printf("  index load    %10.3f ms%s\n", setup_ms, a.no_verify ? "  (mapped, checksum not verified)" : "  (mapped)");
  else
    std::printf("  index build   %10.3f ms\n", setup_ms);
  std::printf("  memory        %10.1f bytes/vector  (raw %.0f)\n", bytes_per_vector, raw_bytes_per_vector);
  std::printf("  search        %10.3f ms  %zu queries%s  (%s)\n", search_ms, nq, a.batch ? ", one batch" : "",
              a.queries.c_str());
  if (a.batch)
    std::printf("  per query     %10.2f us\n", us_per_query);
  else
    std::printf("  per query     %10.2f us  (median %.2f us)\n", us_per_query, Median(per_query_us));
  std::printf("  distances     %10.1f per query  (%.1f%% of the database)\n", computations,
              100.0 * computations / double(n));
  if (!a.save_index.empty()) std::printf("  saved index   %s\n", a.save_index.c_str());
  return 0;
}

int Run(const KnnArgs& a) {
  const bool dump = a.dump_opt->count() > 0;
  const bool search = !a.db.empty() || !a.queries.empty();
  Require(dump || search, ErrorCode::kInvalidArgument,
          "nothing to do: give DB QUERIES --k K, or --dump-descriptors IMAGE... -o OUT.fvecs");
  Require(!(dump && search), ErrorCode::kInvalidArgument,
          "give either DB QUERIES or --dump-descriptors IMAGE..., not both (extra argument '" +
              (a.db.empty() ? a.queries : a.db) + "')");
  if (dump) {
    RejectGiven({a.k_opt, a.mode_opt, a.json_opt, a.batch_opt, a.verify_opt, a.save_opt},
                "applies to searches, not to --dump-descriptors");
    return RunDump(a);
  }
  RejectGiven({a.out_opt, a.max_opt}, "only applies to --dump-descriptors");
  Require(!a.queries.empty(), ErrorCode::kInvalidArgument, "missing QUERIES (an .fvecs file) after DB " + a.db);
  return RunKnn(a);
}

}  // namespace

void RegisterKnn(CLI::App& app, int* code) {
  auto a = std::make_shared<KnnArgs>();
  auto* c = app.add_subcommand("knn", "k nearest neighbours of .fvecs queries (FFVA, approx or brute force)");
  c->add_option("DB", a->db, ".fvecs database, or an index file from --save-index");
  c->add_option("QUERIES", a->queries, ".fvecs queries (same dimension as DB)");
  a->k_opt = c->add_option("--k", a->k, "neighbours per query (1..database size)");
  a->mode_opt = c->add_option("--mode", a->mode, "index: exact (FFVA) | approx (FFVA, thesis block distance) | brute")
                    ->capture_default_str();
  a->json_opt = c->add_flag("--json", a->json, "one JSON object with timings, neighbours and squared distances");
  a->batch_opt = c->add_flag("--batch", a->batch, "search all queries in one SearchBatch call");
  a->save_opt = c->add_option("--save-index", a->save_index, "write the built index here (exact/approx)");
  a->verify_opt = c->add_flag("--no-verify", a->no_verify, "loading an index file: skip its checksum");
  a->dump_opt = c->add_option("--dump-descriptors", a->dump_images,
                              "write the 20-D WH descriptors of these images to -o as .fvecs")
                    ->expected(1, -1);
  a->out_opt = c->add_option("-o,--output", a->output, "--dump-descriptors: .fvecs file to write");
  a->max_opt = c->add_option("--max-per-image", a->max_per_image,
                             "--dump-descriptors: keep the first N descriptors of each image (0: all)")
                   ->capture_default_str();
  c->callback([a, code] { *code = Run(*a); });
}

}  // namespace mvkp::cli
