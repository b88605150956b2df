// mvkp_bench_knn: nearest-neighbour search, mvkp's brute force against FAISS,
// hnswlib and OpenCV FLANN, on one database and query set, single thread.
//
// Per method: build time, microseconds per query (one query per call: median
// over the queries; batched: one call for all queries, total / nq), recall@1
// against exact brute force, and bytes per database vector (heap growth over
// the build, measured with mallinfo2, and, where the library exposes its
// arrays, their sizes, also relative to the raw vectors), and exact distance
// computations per query where the method reports them.
#include <malloc.h>

#include <numeric>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>

#include "datasets.h"
#include "methods.h"
#include "mvkp/core/error.h"
#include "mvkp/core/timer.h"
#include "mvkp/index/fvecs.h"
#include "mvkp/index/knn_index.h"

namespace mvkp::bench {
namespace {

struct Args {
  std::string db, queries;
  std::size_t n = 0, nq = 1000;
  int k = 2;
  bool json = false;
  std::vector<std::string> wh_images, sift_images;
  int dim = 128;
  std::vector<int> random;  // N DIM
  std::vector<std::string> dump;
  bool dump_only = false;
  std::string methods;  // comma-separated filter
  bool list = false;
  unsigned seed = 1;
  double batch_seconds = 1.0;
  int repeat = 1;  // passes over the queries one at a time; the lowest median counts
};

struct Row {
  std::string name, params, structure_how, distances_how;
  std::string error;  // non-empty: the method threw, no numbers
  double build_ms = 0;
  double us_single = 0;       // median over the queries (lowest of the passes)
  double us_single_mean = 0;  // mean over the queries (lowest of the passes)
  std::optional<double> us_batch;
  double recall_single = 0;
  std::optional<double> recall_batch;
  double heap_bytes_per_vector = 0;
  std::optional<double> structure_bytes_per_vector;
  std::optional<double> mem_over_raw;  // structure bytes / (n * dim * 4)
  std::optional<double> distances_per_query;
};

// Memory goal of issue 3 for an index over n vectors of dim floats:
// at most 1.1 x the raw vectors plus one byte per dimension and vector.
double MemoryGoalBytesPerVector(int dim) { return 1.1 * 4.0 * dim + dim; }

// Bytes currently allocated on the heap (arena plus mmap'd blocks).
double HeapBytes() {
  const struct mallinfo2 m = mallinfo2();
  return double(m.uordblks) + double(m.hblkhd);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(h), v.end());
  if (v.size() % 2) return v[h];
  return 0.5 * (v[h] + *std::max_element(v.begin(), v.begin() + std::ptrdiff_t(h)));
}

double Dist64(const float* a, const float* b, int dim) {
  double s = 0;
  for (int d = 0; d < dim; ++d) {
    const double t = double(a[d]) - double(b[d]);
    s += t * t;
  }
  return s;
}

// Exact nearest neighbour of every query by mvkp's brute force (direct
// differences, not the norm expansion), untimed.
std::vector<std::int64_t> GroundTruth(const VectorSet& db, const VectorSet& q) {
  auto index = MakeBruteForceIndex();
  index->Build(db.data.data(), db.n, db.dim, nullptr);
  std::vector<std::int64_t> gt(q.n);
  for (std::size_t i = 0; i < q.n; ++i) {
    Neighbor nb;
    index->Search(q.data.data() + i * std::size_t(q.dim), 1, &nb);
    gt[i] = nb.id;
  }
  return gt;
}

// Share of queries whose first result is the exact nearest neighbour, or a
// vector at the same distance (distances recomputed in double).
double Recall(const VectorSet& db, const VectorSet& q, const std::vector<std::int64_t>& gt,
              const std::vector<std::int64_t>& ids, int k) {
  std::size_t ok = 0;
  for (std::size_t i = 0; i < q.n; ++i) {
    const std::int64_t r = ids[i * std::size_t(k)];
    if (r == gt[i]) {
      ++ok;
      continue;
    }
    if (r < 0 || std::size_t(r) >= db.n) continue;
    const float* x = q.data.data() + i * std::size_t(q.dim);
    if (Dist64(x, db.data.data() + std::size_t(r) * db.dim, db.dim) <=
        Dist64(x, db.data.data() + std::size_t(gt[i]) * db.dim, db.dim))
      ++ok;
  }
  return double(ok) / double(q.n);
}

Row RunMethod(const MethodInfo& info, const VectorSet& db, const VectorSet& q, int k,
              const std::vector<std::int64_t>& gt, double batch_seconds, int repeat) {
  Row row;
  row.name = info.name;
  row.params = info.params;
  row.structure_how = info.structure_how;
  row.distances_how = info.distances_how;
  const double heap0 = HeapBytes();
  Timer t;
  std::unique_ptr<Method> m = info.make();
  m->Build(db.data.data(), db.n, db.dim);
  row.build_ms = t.ElapsedMs();
  row.heap_bytes_per_vector = (HeapBytes() - heap0) / double(db.n);
  if (const double s = m->StructureBytes(); s >= 0) {
    row.structure_bytes_per_vector = s / double(db.n);
    row.mem_over_raw = *row.structure_bytes_per_vector / (4.0 * db.dim);
  }

  const std::size_t kk = std::size_t(k);
  std::vector<std::int64_t> ids(q.n * kk, -1);
  std::vector<float> dists(q.n * kk);
  std::vector<double> us(q.n);
  row.us_single = row.us_single_mean = 1e300;
  for (int pass = 0; pass < repeat; ++pass) {
    m->ResetDistanceCount();
    for (std::size_t i = 0; i < q.n; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      m->SearchOne(q.data.data() + i * std::size_t(q.dim), k, &ids[i * kk], &dists[i * kk]);
      us[i] = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
    }
    row.us_single = std::min(row.us_single, Median(us));
    row.us_single_mean = std::min(row.us_single_mean, std::accumulate(us.begin(), us.end(), 0.0) / double(us.size()));
  }
  row.recall_single = Recall(db, q, gt, ids, k);
  if (const double c = m->DistanceComputations(q.data.data(), q.n, k); c >= 0)
    row.distances_per_query = c / double(q.n);

  if (m->has_batch()) {
    // Best of up to 3 runs, stopping early once batch_seconds have been spent.
    double best = 1e300, spent = 0;
    for (int rep = 0; rep < 3 && (rep == 0 || spent < batch_seconds); ++rep) {
      std::fill(ids.begin(), ids.end(), -1);
      Timer tb;
      m->SearchBatch(q.data.data(), q.n, k, ids.data(), dists.data());
      const double ms = tb.ElapsedMs();
      best = std::min(best, ms);
      spent += ms / 1000;
    }
    row.us_batch = best * 1000 / double(q.n);
    row.recall_batch = Recall(db, q, gt, ids, k);
  }
  return row;
}

std::string Fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

void PrintTable(const Dataset& d, int k, const std::vector<Row>& rows, const std::vector<std::string>& env) {
  std::printf("data: %s\n", d.source.c_str());
  std::printf("n=%zu nq=%zu dim=%d k=%d, single thread; generated/loaded in %.1f s\n", d.db.n, d.queries.n, d.db.dim,
              k, d.generate_ms / 1000);
  for (const auto& e : env) std::printf("%s\n", e.c_str());
  const double raw = 4.0 * d.db.dim, goal = MemoryGoalBytesPerVector(d.db.dim);
  std::printf("memory goal (issue 3): <= 1.1 x raw + 1 B/dim/vector = %.1f B/vec at dim %d (raw %.0f), i.e. mem/raw <= %.3f\n",
              goal, d.db.dim, raw, goal / raw);
  std::printf("\n%-16s %11s %12s %10s %11s %9s %11s %11s %8s %10s\n", "method", "build ms", "us/q single", "mean",
              "us/q batch", "recall@1", "B/vec heap", "B/vec struct", "mem/raw", "dist/q");
  for (const Row& r : rows) {
    if (!r.error.empty()) {
      std::printf("%-16s FAILED: %s\n", r.name.c_str(), r.error.c_str());
      continue;
    }
    std::string recall = Fixed(r.recall_single, 4);
    if (r.recall_batch && std::abs(*r.recall_batch - r.recall_single) > 1e-12) recall += "/" + Fixed(*r.recall_batch, 4);
    std::string dist = "-";
    if (r.distances_per_query) dist = Fixed(*r.distances_per_query, *r.distances_per_query >= 100 ? 0 : 1);
    std::printf("%-16s %11s %12s %10s %11s %9s %11s %11s %8s %10s\n", r.name.c_str(), Fixed(r.build_ms, 1).c_str(),
                Fixed(r.us_single, 2).c_str(), Fixed(r.us_single_mean, 2).c_str(), r.us_batch ? Fixed(*r.us_batch, 2).c_str() : "-", recall.c_str(),
                Fixed(r.heap_bytes_per_vector, 1).c_str(),
                r.structure_bytes_per_vector ? Fixed(*r.structure_bytes_per_vector, 1).c_str() : "-",
                r.mem_over_raw ? Fixed(*r.mem_over_raw, 3).c_str() : "-", dist.c_str());
  }
  std::printf("\n");
  for (const Row& r : rows) std::printf("  %-16s %s\n", r.name.c_str(), r.params.c_str());
  std::printf(
      "us/q single: median over queries, one query per call (lowest of --repeat passes), mean: their mean (ditto);\n"
      "us/q batch: all queries in one call, total/nq (best of <= 3), to be compared with the mean.\nrecall@1: first result is the exact nearest (mvkp brute-force Search) or at the same distance; "
      "a/b = single/batch when they differ.\nB/vec heap: heap growth over the build (mallinfo2) / n; "
      "B/vec struct: the index's arrays as the library exposes them / n; mem/raw: B/vec struct / (4 * dim).\n"
      "dist/q: exact distance computations per query in the single-query pass (- = not reported).\n");
}

nlohmann::json ToJson(const Dataset& d, int k, int repeat, const std::vector<Row>& rows,
                      const std::vector<std::string>& env) {
  using nlohmann::json;
  json methods = json::array();
  for (const Row& r : rows) {
    if (!r.error.empty()) {
      methods.push_back({{"name", r.name}, {"params", r.params}, {"error", r.error}});
      continue;
    }
    methods.push_back({{"name", r.name},
                       {"params", r.params},
                       {"build_ms", r.build_ms},
                       {"us_per_query_single_median", r.us_single},
                       {"us_per_query_single_mean", r.us_single_mean},
                       {"us_per_query_batch", r.us_batch ? json(*r.us_batch) : json(nullptr)},
                       {"recall_at_1_single", r.recall_single},
                       {"recall_at_1_batch", r.recall_batch ? json(*r.recall_batch) : json(nullptr)},
                       {"bytes_per_vector_heap", r.heap_bytes_per_vector},
                       {"bytes_per_vector_structure",
                        r.structure_bytes_per_vector ? json(*r.structure_bytes_per_vector) : json(nullptr)},
                       {"structure_how", r.structure_how},
                       {"mem_over_raw", r.mem_over_raw ? json(*r.mem_over_raw) : json(nullptr)},
                       {"distance_computations_per_query",
                        r.distances_per_query ? json(*r.distances_per_query) : json(nullptr)},
                       {"distances_how", r.distances_how}});
  }
  return {{"data",
           {{"source", d.source},
            {"n", d.db.n},
            {"nq", d.queries.n},
            {"dim", d.db.dim},
            {"k", k},
            {"generate_ms", d.generate_ms}}},
          {"threads", 1},
          {"repeat", repeat},
          {"timing",
           "single: median (and mean) us over queries, one per call, lowest of " + std::to_string(repeat) +
               " pass(es); batch: one call for all queries, best of <= 3, total/nq"},
          {"environment", env},
          {"ground_truth", "mvkp brute-force Search(k=1); a result at the same distance (double) counts as correct"},
          {"bytes_per_vector_heap_how", "mallinfo2 uordblks+hblkhd after build minus before, / n"},
          {"memory_goal",
           {{"rule", "structure <= 1.1 x raw + 1 byte per dimension and vector"},
            {"bytes_per_vector", MemoryGoalBytesPerVector(d.db.dim)},
            {"mem_over_raw", MemoryGoalBytesPerVector(d.db.dim) / (4.0 * d.db.dim)}}},
          {"methods", methods}};
}

std::vector<MethodInfo> SelectMethods(const std::string& filter) {
  std::vector<MethodInfo> all = AllMethods();
  if (filter.empty()) return all;
  std::set<std::string> want;
  std::stringstream ss(filter);
  for (std::string name; std::getline(ss, name, ',');)
    if (!name.empty()) want.insert(name);
  std::vector<MethodInfo> out;
  for (auto& m : all)
    if (want.erase(m.name)) out.push_back(std::move(m));
  if (!want.empty())
    throw Error(ErrorCode::kInvalidArgument,
                "--methods: unknown or not compiled in: " + *want.begin() + " (see --list-methods)");
  return out;
}

int Run(Args& a) {
  if (a.list) {
    for (const auto& m : AllMethods()) std::printf("%s\n", m.name.c_str());
    return 0;
  }
  const int modes = int(!a.db.empty() || !a.queries.empty()) + int(!a.wh_images.empty()) +
                    int(!a.sift_images.empty()) + int(!a.random.empty());
  Require(modes == 1, ErrorCode::kInvalidArgument,
          "give exactly one of --db/--queries, --generate-wh, --generate-sift, --random (see --help)");
  Require(a.k >= 1, ErrorCode::kInvalidArgument, "--k must be >= 1");
  const std::vector<MethodInfo> methods = SelectMethods(a.methods);

  Dataset d;
  if (!a.db.empty() || !a.queries.empty()) {
    Require(!a.db.empty() && !a.queries.empty(), ErrorCode::kInvalidArgument, "--db and --queries go together");
    Timer t;
    d.db = ReadFvecs(a.db, a.n);
    d.queries = ReadFvecs(a.queries, a.nq);
    Require(d.db.dim == d.queries.dim, ErrorCode::kInvalidArgument,
            "database dimension " + std::to_string(d.db.dim) + " != query dimension " + std::to_string(d.queries.dim));
    d.source = a.db + " (queries " + a.queries + ")";
    d.generate_ms = t.ElapsedMs();
  } else if (!a.random.empty()) {
    Require(a.random[0] >= 1 && a.random[1] >= 1 && a.random[1] <= kMaxFvecsDim, ErrorCode::kInvalidArgument,
            "--random N DIM: N >= 1, 1 <= DIM <= 65536");
    d = RandomDataset(std::size_t(a.random[0]), a.random[1], a.nq, a.seed);
  } else {
    Require(a.n >= 1, ErrorCode::kInvalidArgument, "--generate-wh/--generate-sift need --n");
    const bool wh = !a.wh_images.empty();
    std::fprintf(stderr, "generating %s descriptors...\n", wh ? "WH" : "SIFT");
    d = ImageDataset(wh ? Descriptor::kWh : Descriptor::kSift, wh ? a.wh_images : a.sift_images, a.n, a.nq, a.dim,
                     a.seed);
  }
  Require(d.db.n >= std::size_t(a.k), ErrorCode::kInvalidArgument, "--k exceeds the database size");
  if (!a.dump.empty()) {
    WriteFvecs(a.dump[0], d.db.data.data(), d.db.n, d.db.dim);
    WriteFvecs(a.dump[1], d.queries.data.data(), d.queries.n, d.queries.dim);
    std::fprintf(stderr, "wrote %s (%zu x %d) and %s (%zu)\n", a.dump[0].c_str(), d.db.n, d.db.dim, a.dump[1].c_str(),
                 d.queries.n);
  }
  if (a.dump_only) {
    std::printf("data: %s\nn=%zu nq=%zu dim=%d; generated/loaded in %.1f s\n", d.source.c_str(), d.db.n, d.queries.n,
                d.db.dim, d.generate_ms / 1000);
    return 0;
  }

  Timer gt_timer;
  const std::vector<std::int64_t> gt = GroundTruth(d.db, d.queries);
  std::fprintf(stderr, "ground truth: %.1f s\n", gt_timer.ElapsedMs() / 1000);

  std::vector<Row> rows;
  for (const auto& m : methods) {
    Timer t;
    // A method that throws gets an error row; the others still run.
    try {
      rows.push_back(RunMethod(m, d.db, d.queries, a.k, gt, a.batch_seconds, a.repeat));
      std::fprintf(stderr, "%-16s done in %.1f s\n", m.name.c_str(), t.ElapsedMs() / 1000);
    } catch (const std::exception& e) {
      Row r;
      r.name = m.name;
      r.params = m.params;
      r.error = e.what();
      rows.push_back(r);
      std::fprintf(stderr, "%-16s FAILED: %s\n", m.name.c_str(), e.what());
    }
  }
  const bool failed = std::any_of(rows.begin(), rows.end(), [](const Row& r) { return !r.error.empty(); });

  std::vector<std::string> env;
  env.push_back(std::string("mvkp brute force kernels: ") +
                (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") ? "AVX2+FMA" : "scalar"));
  if (auto s = FaissEnvironment(); !s.empty()) env.push_back(s);
  if (auto s = HnswlibEnvironment(); !s.empty()) env.push_back(s);
  if (a.json)
    std::printf("%s\n", ToJson(d, a.k, a.repeat, rows, env).dump(2).c_str());
  else
    PrintTable(d, a.k, rows, env);
  return failed ? 1 : 0;
}

}  // namespace
}  // namespace mvkp::bench

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  mvkp::bench::SingleThreaded();
  mvkp::bench::Args a;
  CLI::App app{
      "mvkp_bench_knn - nearest-neighbour search: mvkp brute force vs FAISS, hnswlib, OpenCV FLANN (single thread)"};
  app.add_option("--db", a.db, "database .fvecs");
  app.add_option("--queries", a.queries, "query .fvecs");
  app.add_option("--n", a.n, "database size (files: read the first N, 0 = all; --generate-*: required)");
  app.add_option("--nq", a.nq, "number of queries (files: the first M)")->capture_default_str();
  app.add_option("--k", a.k, "neighbours per query")->capture_default_str();
  app.add_flag("--json", a.json, "print a JSON object instead of the table");
  app.add_option("--generate-wh", a.wh_images, "build database and queries from mvkp WH descriptors of these images");
  app.add_option("--generate-sift", a.sift_images, "... from OpenCV SIFT descriptors of these images");
  app.add_option("--dim", a.dim, "SIFT dimension: 128, or 64 (PCA fitted on the database)")
      ->capture_default_str()
      ->check(CLI::IsMember({64, 128}));
  app.add_option("--random", a.random, "random uniform data: N DIM")->expected(2);
  auto* dump = app.add_option("--dump", a.dump, "save the database and queries used: DB.fvecs Q.fvecs")->expected(2);
  app.add_flag("--dump-only", a.dump_only, "with --dump: write the files and exit without benchmarking")->needs(dump);
  app.add_option("--methods", a.methods, "comma-separated subset of the methods (default: all)");
  app.add_flag("--list-methods", a.list, "print the compiled-in methods and exit");
  app.add_option("--seed", a.seed, "seed for random data and sampling")->capture_default_str();
  app.add_option("--batch-seconds", a.batch_seconds, "repeat batched runs (up to 3) while under this time")
      ->capture_default_str();
  app.add_option("--repeat", a.repeat, "passes of one-query-per-call timing; the lowest median (and mean) is reported")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  try {
    app.parse(argc, argv);
    return mvkp::bench::Run(a);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const mvkp::Error& e) {
    std::fprintf(stderr, "mvkp_bench_knn: error: %s\n", e.what());
    return 1;
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "mvkp_bench_knn: OpenCV error: %s\n", e.err.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvkp_bench_knn: error: %s\n", e.what());
    return 1;
  }
}
