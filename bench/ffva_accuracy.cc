// mvkp_ffva_accuracy: what FFVA's approximate mode (the thesis's
// corner-to-corner block distance) gives up, in the style of thesis Table 5.2.
//
// Thesis protocol (§5.2.1): a synthetic database of uniformly distributed
// vectors; 1000 of them, with Gaussian noise of variance 0.3 added, are the
// queries; a query is answered correctly when its nearest neighbour is the
// vector it came from. Here the database holds integers in [0, 255] (the
// thesis's WH projections are integers), 15 000 vectors as in its Fig. 5.3,
// dimensions 60..150. Each row gives correct answers out of 1000 for FFVA
// exact, FFVA approx and brute force, recall@1 of approx against exact, and
// exact distance computations per query (Fig. 5.3's measure).
//
// --real DB.fvecs Q.fvecs repeats the comparison on real descriptors (no
// source vectors there: recall@1 of approx against brute force only).
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "mvkp/core/error.h"
#include "mvkp/index/ffva.h"
#include "mvkp/index/fvecs.h"

namespace {

struct Result {
  std::string data;
  int dim = 0;
  std::size_t n = 0, nq = 0;
  long correct_exact = -1, correct_approx = -1, correct_brute = -1;  // -1: no ground truth
  double recall_approx = 0;                                         // approx NN == exact NN (by distance)
  double dist_exact = 0, dist_approx = 0;                           // exact distance computations per query
};

Result Run(const std::string& data, const std::vector<float>& db, std::size_t n, const std::vector<float>& q,
           std::size_t nq, int dim, const std::vector<std::int32_t>* truth) {
  Result r;
  r.data = data;
  r.dim = dim;
  r.n = n;
  r.nq = nq;
  auto brute = mvkp::MakeIndexByName("brute");
  auto exact = mvkp::MakeIndexByName("exact");
  auto approx = mvkp::MakeIndexByName("approx");
  for (auto* idx : {brute.get(), exact.get(), approx.get()}) {
    idx->Build(db.data(), n, dim, nullptr);
    idx->ResetStats();
  }
  long ce = 0, ca = 0, cb = 0, agree = 0;
  for (std::size_t i = 0; i < nq; ++i) {
    const float* x = q.data() + i * dim;
    mvkp::Neighbor b[1], e[1], a[1];
    brute->Search(x, 1, b);
    exact->Search(x, 1, e);
    approx->Search(x, 1, a);
    agree += a[0].distance == b[0].distance;
    if (truth) {
      cb += b[0].id == (*truth)[i];
      ce += e[0].id == (*truth)[i];
      ca += a[0].id == (*truth)[i];
    }
  }
  if (truth) {
    r.correct_exact = ce;
    r.correct_approx = ca;
    r.correct_brute = cb;
  }
  r.recall_approx = double(agree) / double(nq);
  r.dist_exact = double(exact->distance_computations()) / double(nq);
  r.dist_approx = double(approx->distance_computations()) / double(nq);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"FFVA approximate-mode accuracy, thesis Table 5.2 protocol"};
  std::vector<int> dims = {60, 70, 80, 90, 100, 110, 115, 120, 125, 130, 135, 140, 145, 150};
  std::size_t n = 15000, nq = 1000;
  double noise_var = 0.3;
  unsigned seed = 1;
  std::vector<std::string> real;
  bool json = false;
  app.add_option("--dims", dims, "synthetic dimensions")->capture_default_str();
  app.add_option("--n", n, "synthetic database size")->capture_default_str();
  app.add_option("--nq", nq, "queries")->capture_default_str();
  app.add_option("--noise-var", noise_var, "variance of the Gaussian noise added to queries")->capture_default_str();
  app.add_option("--seed", seed, "random seed")->capture_default_str();
  app.add_option("--real", real, "DB.fvecs QUERIES.fvecs: also compare on real descriptors")->expected(2);
  app.add_flag("--json", json, "print JSON instead of a table");
  CLI11_PARSE(app, argc, argv);
  try {
    mvkp::Require(n >= 1 && nq >= 1 && nq <= n, mvkp::ErrorCode::kInvalidArgument, "need 1 <= nq <= n");
    std::vector<Result> rows;
    for (int dim : dims) {
      mvkp::Require(dim >= 1 && dim <= 4096, mvkp::ErrorCode::kInvalidArgument, "dimensions must be in 1..4096");
      std::mt19937 rng(seed * 7919u + unsigned(dim));
      std::uniform_int_distribution<int> value(0, 255);
      std::normal_distribution<float> noise(0.f, float(std::sqrt(noise_var)));
      std::vector<float> db(n * dim), q(nq * dim);
      for (auto& v : db) v = float(value(rng));
      std::vector<std::int32_t> truth(nq);
      for (std::size_t i = 0; i < nq; ++i) {
        truth[i] = std::int32_t(rng() % n);
        for (int d = 0; d < dim; ++d) q[i * dim + d] = db[std::size_t(truth[i]) * dim + d] + noise(rng);
      }
      rows.push_back(Run("uniform-int", db, n, q, nq, dim, &truth));
    }
    if (!real.empty()) {
      const mvkp::VectorSet db = mvkp::ReadFvecs(real[0]);
      const mvkp::VectorSet q = mvkp::ReadFvecs(real[1]);
      mvkp::Require(db.dim == q.dim, mvkp::ErrorCode::kInvalidArgument, "dimension mismatch between --real files");
      mvkp::Require(db.n > 0 && q.n > 0, mvkp::ErrorCode::kInvalidArgument, "empty --real file");
      rows.push_back(Run(real[0], db.data, db.n, q.data, q.n, db.dim, nullptr));
    }
    if (json) {
      nlohmann::json out = nlohmann::json::array();
      for (const Result& r : rows)
        out.push_back({{"data", r.data}, {"dim", r.dim}, {"n", r.n}, {"nq", r.nq}, {"correct_exact", r.correct_exact},
                       {"correct_approx", r.correct_approx}, {"correct_brute", r.correct_brute},
                       {"recall_approx_vs_exact", r.recall_approx}, {"dist_per_query_exact", r.dist_exact},
                       {"dist_per_query_approx", r.dist_approx}});
      std::printf("%s\n", out.dump(2).c_str());
    } else {
      std::printf("%-14s %5s %7s %6s | correct of nq: %6s %6s %6s | approx recall@1 | dist/q exact approx\n", "data",
                  "dim", "n", "nq", "brute", "exact", "approx");
      for (const Result& r : rows) {
        auto c = [](long v) { return v < 0 ? std::string("-") : std::to_string(v); };
        std::printf("%-14s %5d %7zu %6zu |                %6s %6s %6s | %15.4f | %12.1f %6.1f\n",
                    r.data.size() > 14 ? r.data.substr(r.data.size() - 14).c_str() : r.data.c_str(), r.dim, r.n,
                    r.nq, c(r.correct_brute).c_str(), c(r.correct_exact).c_str(), c(r.correct_approx).c_str(),
                    r.recall_approx, r.dist_exact, r.dist_approx);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvkp_ffva_accuracy: %s\n", e.what());
    return 1;
  }
  return 0;
}
