#include "mvkp/serve/service.h"

#include <httplib.h>
#include <malloc.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <future>
#include <list>
#include <map>
#include <mutex>
#include <optional>
#include <semaphore>
#include <set>
#include <shared_mutex>
#include <thread>
#include <unordered_map>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/db/json_limits.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/pose/pose.h"
#include "mvkp/quality/db_quality.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/serve/encode.h"
#include "mvkp/serve/internal/conn_deadline.h"
#include "mvkp/serve/site.h"
#include "mvkp/serve/web_assets.h"

namespace mvkp::serve {

void ServiceOptions::Check() const {
  Require(!db.empty(), ErrorCode::kInvalidArgument, "serve: no database given");
  Require(port >= 0 && port <= 65535, ErrorCode::kInvalidArgument, "serve: port must be in 0..65535");
  Require(backlog >= 1 && backlog <= 65535, ErrorCode::kInvalidArgument, "serve: backlog must be in 1..65535");
  Require(threads >= 1 && threads <= 256, ErrorCode::kInvalidArgument, "serve: threads must be in 1..256");
  Require(io_threads >= 2 && io_threads <= 4096, ErrorCode::kInvalidArgument, "serve: io threads must be in 2..4096");
  Require(max_inflight >= 0, ErrorCode::kInvalidArgument, "serve: max inflight must be >= 0");
  Require(max_body_mb >= 1 && max_body_mb <= 1024, ErrorCode::kInvalidArgument, "serve: max body must be 1..1024 MiB");
  Require(max_pixels >= 256, ErrorCode::kInvalidArgument, "serve: max pixels must be >= 256");
  Require(timeout_s >= 1 && timeout_s <= 3600, ErrorCode::kInvalidArgument, "serve: timeout must be in 1..3600 s");
  Require(read_deadline_s >= 0.5 && read_deadline_s <= 86400, ErrorCode::kInvalidArgument,
          "serve: the read deadline must be in 0.5..86400 s");
  Require(max_connection_s >= 1 && max_connection_s <= 86400, ErrorCode::kInvalidArgument,
          "serve: the connection limit must be in 1..86400 s");
  Require(watch_s >= 0 && watch_s <= 86400, ErrorCode::kInvalidArgument, "serve: watch period must be in 0..86400 s");
  Require(admin_token.empty() || admin_token.size() >= 16, ErrorCode::kInvalidArgument,
          "serve: the admin token must be at least 16 characters");
  Require(token_failures_before_delay >= 1, ErrorCode::kInvalidArgument, "serve: token failures must be >= 1");
  Require(probe_words >= 0 && probe_words <= 65536, ErrorCode::kInvalidArgument, "serve: probe words must be in 0..65536");
  Require(cert.empty() == key.empty(), ErrorCode::kInvalidArgument,
          "serve: HTTPS needs both a certificate and its private key (--cert and --key)");
}

namespace {

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// The kind under which the admin API stores an exhibit's quality report
// (QualityJson without the points) beside its model.
constexpr const char* kQualityEncoding = "quality";

// PUT bodies: metadata only.
constexpr std::size_t kMaxPutBytes = 96 << 10;

// The static pages load only their own scripts, styles and images (the
// client's photo preview is a blob: URL), are never framed, and their
// types are not sniffed.
constexpr const char* kContentSecurityPolicy =
    "default-src 'self'; img-src 'self' blob: data:; media-src 'self' blob: mediastream:; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'; form-action 'self'";

void SendError(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(Dump(Json{{"error", message}}), "application/json");
}

// Request counts and latency histograms per route and status, in the
// Prometheus text format.
class Metrics {
 public:
  void Observe(const std::string& route, int status, double seconds) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++count_[{route, status}];
    auto& h = hist_[route];
    h.sum += seconds;
    ++h.n;
    for (std::size_t i = 0; i < kBounds.size(); ++i)
      if (seconds <= kBounds[i]) ++h.buckets[i];
  }
  std::string Text() const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string out = "# HELP mvkp_requests_total HTTP requests by route and status.\n# TYPE mvkp_requests_total counter\n";
    for (const auto& [k, v] : count_)
      out += "mvkp_requests_total{route=\"" + k.first + "\",status=\"" + std::to_string(k.second) + "\"} " +
             std::to_string(v) + "\n";
    out += "# HELP mvkp_request_seconds Request latency.\n# TYPE mvkp_request_seconds histogram\n";
    for (const auto& [route, h] : hist_) {
      for (std::size_t i = 0; i < kBounds.size(); ++i)
        out += "mvkp_request_seconds_bucket{route=\"" + route + "\",le=\"" + Num(kBounds[i]) + "\"} " +
               std::to_string(h.buckets[i]) + "\n";
      out += "mvkp_request_seconds_bucket{route=\"" + route + "\",le=\"+Inf\"} " + std::to_string(h.n) + "\n";
      out += "mvkp_request_seconds_sum{route=\"" + route + "\"} " + Num(h.sum) + "\n";
      out += "mvkp_request_seconds_count{route=\"" + route + "\"} " + std::to_string(h.n) + "\n";
    }
    return out;
  }
  static std::string Num(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }

 private:
  static constexpr std::array<double, 10> kBounds = {0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5};
  struct Hist {
    std::array<std::uint64_t, 10> buckets{};
    std::uint64_t n = 0;
    double sum = 0;
  };
  mutable std::mutex mutex_;
  std::map<std::pair<std::string, int>, std::uint64_t> count_;
  std::map<std::string, Hist> hist_;
};

// The routes: a path's label (ids replaced, for metrics and logs) and the
// methods it takes (for 405 and Allow).
struct RouteInfo {
  std::string label;
  std::string allow;  // "" for an unknown path
};

RouteInfo RouteOf(const std::string& p) {
  static const std::string kExhibit = "/api/exhibits/";
  if (p.rfind(kExhibit, 0) == 0) {
    const std::string rest = p.substr(kExhibit.size());
    const auto slash = rest.find('/');
    if (slash == std::string::npos) return {"/api/exhibits/{id}", rest.empty() ? "" : "GET, HEAD, PUT, DELETE"};
    const std::string tail = rest.substr(slash);
    if (slash == 0) return {"other", ""};
    if (tail == "/image") return {"/api/exhibits/{id}/image", "GET, HEAD, PUT"};
    if (tail == "/quality") return {"/api/exhibits/{id}/quality", "GET, HEAD"};
    return {"other", ""};
  }
  if (p == "/api/recognize") return {p, "POST"};
  if (p == "/api/exhibits") return {p, "GET, HEAD, POST"};
  if (p == "/api/admin/check" || p == "/api/admin/quality" || p == "/healthz" || p == "/metrics" || p == "/api/site" || p == "/api/site/logo")
    return {p, "GET, HEAD"};
  if (p == "/admin" || p == "/admin.html" || p == "/admin.js" || p == "/admin.css") return {"/admin", "GET, HEAD"};
  if (FindWebAsset(p)) return {"/", "GET, HEAD"};
  return {"other", ""};
}

thread_local bool t_overloaded = false;  // this connection came over the bound: answer 503
thread_local Clock::time_point t_request_start;  // set before routing, read by the logger

// httplib hands each accepted connection to a task queue; its ThreadPool
// queues without bound, so excess load would pile up unseen by the handlers.
// This queue lets at most max_pending connections wait for or occupy the
// workers; the others go to one extra thread that answers 503 at once.
class BoundedQueue : public httplib::TaskQueue {
 public:
  BoundedQueue(std::size_t threads, std::size_t max_pending) : workers_(threads), rejecter_(1), max_(max_pending) {}
  void enqueue(std::function<void()> fn) override {
    if (pending_.fetch_add(1) >= max_) {
      pending_.fetch_sub(1);
      rejecter_.enqueue([fn] {
        t_overloaded = true;
        fn();
        t_overloaded = false;
      });
      return;
    }
    workers_.enqueue([this, fn] {
      fn();
      pending_.fetch_sub(1);
    });
  }
  void shutdown() override {
    workers_.shutdown();
    rejecter_.shutdown();
  }

 private:
  httplib::ThreadPool workers_, rejecter_;
  std::size_t max_;
  std::atomic<std::size_t> pending_{0};
};

// CPU work runs at most `n` at a time.
class CpuGate {
 public:
  explicit CpuGate(int n) : sem_(n) {}
  struct Slot {
    CpuGate* g;
    ~Slot() { g->sem_.release(); }
  };
  Slot Acquire() {
    sem_.acquire();
    return {this};
  }

 private:
  std::counting_semaphore<4096> sem_;
};

// Thumbnails by exhibit, time of addition and size, least recently used
// dropped first, at most `max_bytes` in all.
class ThumbCache {
 public:
  explicit ThumbCache(std::size_t max_bytes) : max_(max_bytes) {}
  std::optional<std::string> Get(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = index_.find(key);
    if (it == index_.end()) {
      ++misses_;
      return std::nullopt;
    }
    ++hits_;
    lru_.splice(lru_.begin(), lru_, it->second);
    return it->second->second;
  }
  void Put(const std::string& key, std::string jpeg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (jpeg.size() > max_ || index_.count(key)) return;
    bytes_ += jpeg.size();
    lru_.emplace_front(key, std::move(jpeg));
    index_[key] = lru_.begin();
    while (bytes_ > max_) {
      bytes_ -= lru_.back().second.size();
      index_.erase(lru_.back().first);
      lru_.pop_back();
    }
  }
  void Clear() {
    std::lock_guard<std::mutex> lock(mutex_);
    lru_.clear();
    index_.clear();
    bytes_ = 0;
  }
  std::string Metrics() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return "# HELP mvkp_thumb_cache_bytes Thumbnails held in memory.\n# TYPE mvkp_thumb_cache_bytes gauge\n"
           "mvkp_thumb_cache_bytes " + std::to_string(bytes_) +
           "\n# HELP mvkp_thumb_cache_hits_total Thumbnails served from memory.\n"
           "# TYPE mvkp_thumb_cache_hits_total counter\nmvkp_thumb_cache_hits_total " + std::to_string(hits_) +
           "\n# HELP mvkp_thumb_cache_misses_total Thumbnails decoded.\n"
           "# TYPE mvkp_thumb_cache_misses_total counter\nmvkp_thumb_cache_misses_total " + std::to_string(misses_) +
           "\n";
  }

 private:
  std::size_t max_, bytes_ = 0;
  std::uint64_t hits_ = 0, misses_ = 0;
  std::list<std::pair<std::string, std::string>> lru_;
  std::unordered_map<std::string, std::list<std::pair<std::string, std::string>>::iterator> index_;
  mutable std::mutex mutex_;
};

// Wrong admin tokens, by client address: after `free` failures each further
// attempt must wait twice as long as the last (0.5 s, 1 s, ... up to 5 min),
// answered 429 until then. A right token clears the address.
class TokenGuard {
 public:
  explicit TokenGuard(int free) : free_(free) {}
  // Seconds to wait before trying again (0: go ahead).
  double Blocked(const std::string& addr) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = by_addr_.find(addr);
    if (it == by_addr_.end()) return 0;
    const double s = std::chrono::duration<double>(it->second.until - Clock::now()).count();
    return s > 0 ? s : 0;
  }
  void Failed(const std::string& addr) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (by_addr_.size() > 10000) {  // bounded: forget addresses that are not blocked
      for (auto it = by_addr_.begin(); it != by_addr_.end();)
        it = it->second.until < Clock::now() ? by_addr_.erase(it) : std::next(it);
    }
    auto& e = by_addr_[addr];
    ++e.failures;
    ++total_;
    if (e.failures >= free_) {
      const double wait = std::min(300.0, 0.5 * std::pow(2.0, std::min(20, e.failures - free_)));
      e.until = Clock::now() + std::chrono::milliseconds(std::int64_t(wait * 1000));
    }
  }
  void Succeeded(const std::string& addr) {
    std::lock_guard<std::mutex> lock(mutex_);
    by_addr_.erase(addr);
  }
  std::uint64_t total() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return total_;
  }

 private:
  struct Entry {
    int failures = 0;
    Clock::time_point until{};
  };
  int free_;
  std::uint64_t total_ = 0;
  std::map<std::string, Entry> by_addr_;
  mutable std::mutex mutex_;
};

// Longer side kept when a request's JPEG is decoded reduced: 1.5x the
// recogniser's 1280 px working size, so a 4032 px photo decodes at 2016 px
// and an 8000 px one at 2000 px.
constexpr int kRecognizeMinSide = 1920;

// A stored image decoded for the service: at full size if within
// `max_pixels`, else (JPEG) at 1/2, 1/4 or 1/8 when that fits; otherwise an
// Error(kBadImage) saying so.
cv::Mat DecodeStored(const std::string& name, const std::vector<std::uint8_t>& bytes, std::int64_t max_pixels,
                     bool color, int min_reduce = 1) {
  const ImageHeader h = ReadImageHeader(name, bytes.data(), bytes.size());
  Require(h.complete, ErrorCode::kBadImage, name + ": " + h.incomplete);
  const std::int64_t px = std::int64_t(h.width) * h.height;
  int reduce = std::max(1, min_reduce);
  if (h.format != "jpeg") reduce = 1;
  while (reduce < 8 && px > 0 && (px + std::int64_t(reduce) * reduce - 1) / (std::int64_t(reduce) * reduce) > max_pixels)
    reduce *= 2;
  const std::int64_t decoded = px / (std::int64_t(reduce) * reduce);
  Require(px > 0 && decoded <= max_pixels, ErrorCode::kBadImage,
          name + " is " + std::to_string(h.width) + "x" + std::to_string(h.height) +
              ", above this server's pixel limit (" + std::to_string(max_pixels) + ")");
  if (reduce == 1 && !color) {
    ImageLimits lim;
    lim.max_pixels = max_pixels;
    return DecodeImageGray(name, bytes, lim);
  }
  const int flags = reduce == 8   ? (color ? cv::IMREAD_REDUCED_COLOR_8 : cv::IMREAD_REDUCED_GRAYSCALE_8)
                    : reduce == 4 ? (color ? cv::IMREAD_REDUCED_COLOR_4 : cv::IMREAD_REDUCED_GRAYSCALE_4)
                    : reduce == 2 ? (color ? cv::IMREAD_REDUCED_COLOR_2 : cv::IMREAD_REDUCED_GRAYSCALE_2)
                                  : (color ? cv::IMREAD_COLOR : cv::IMREAD_GRAYSCALE);
  cv::Mat img = cv::imdecode(bytes, flags);
  Require(!img.empty(), ErrorCode::kBadImage, name + ": cannot be decoded");
  return img;
}

double Param(const httplib::Request& req, const char* name, double fallback) {
  if (!req.has_param(name)) return fallback;
  const std::string v = req.get_param_value(name);
  std::size_t used = 0;
  double x = 0;
  try {
    x = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size() || !std::isfinite(x)) throw Error(ErrorCode::kInvalidArgument, std::string("bad number for ") + name);
  return x;
}

void DefaultLog(const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); }

// OpenSSL's reason for the last failure ("" when it gave none), clearing its queue.
std::string SslReason() {
  std::string out;
  while (const unsigned long e = ::ERR_get_error()) {
    char b[256];
    ::ERR_error_string_n(e, b, sizeof b);
    out = b;  // the last is the most specific
  }
  return out.empty() ? "" : " (" + out + ")";
}

// Checks the certificate and key as httplib's SSLServer will load them, so
// that a bad file is an error naming it and saying what is wrong (httplib
// only says "not valid").
void CheckTlsFiles(const std::string& cert, const std::string& key) {
  for (const std::string* f : {&cert, &key}) {
    std::error_code ec;
    const char* what = f == &cert ? "certificate" : "private key";
    Require(std::filesystem::exists(*f, ec), ErrorCode::kIo, "serve: " + std::string(what) + " " + *f + ": no such file");
    std::FILE* in = std::fopen(f->c_str(), "rb");
    Require(in != nullptr, ErrorCode::kIo, "serve: " + std::string(what) + " " + *f + ": cannot be read");
    std::fclose(in);
  }
  std::unique_ptr<SSL_CTX, void (*)(SSL_CTX*)> ctx(::SSL_CTX_new(::TLS_server_method()), ::SSL_CTX_free);
  Require(ctx != nullptr, ErrorCode::kIo, "serve: cannot set up TLS" + SslReason());
  ::ERR_clear_error();
  Require(::SSL_CTX_use_certificate_chain_file(ctx.get(), cert.c_str()) == 1, ErrorCode::kInvalidArgument,
          "serve: certificate " + cert + " is not a PEM certificate" + SslReason());
  Require(::SSL_CTX_use_PrivateKey_file(ctx.get(), key.c_str(), SSL_FILETYPE_PEM) == 1, ErrorCode::kInvalidArgument,
          "serve: private key " + key + " is not an unencrypted PEM private key, or not the certificate's" + SslReason());
  Require(::SSL_CTX_check_private_key(ctx.get()) == 1, ErrorCode::kInvalidArgument,
          "serve: private key " + key + " does not belong to certificate " + cert + SslReason());
}

// HTTP, or HTTPS when a certificate is given (checked first).
std::unique_ptr<httplib::Server> MakeServer(const ServiceOptions& a) {
  if (a.cert.empty()) return std::make_unique<httplib::Server>();
  CheckTlsFiles(a.cert, a.key);
  auto s = std::make_unique<httplib::SSLServer>(a.cert.c_str(), a.key.c_str());
  Require(s->is_valid(), ErrorCode::kInvalidArgument,
          "serve: cannot use certificate " + a.cert + " with key " + a.key + SslReason());
  return s;
}

// The exhibits a client saw in its last frame, `?prev=a,b,c` (or repeated
// `prev` parameters): at most kMaxPrev distinct ids, each 1..256 bytes of
// UTF-8 without control characters (the store's rules for any stored id).
// An empty value means none; an empty item, a bad id or too many ids throw
// Error(kInvalidArgument) naming what was wrong. Duplicates count once.
constexpr std::size_t kMaxPrev = 20;

std::vector<std::string> ParsePrev(const httplib::Request& req) {
  std::vector<std::string> ids;
  const std::size_t n = req.get_param_value_count("prev");
  for (std::size_t k = 0; k < n; ++k) {
    const std::string v = req.get_param_value("prev", k);
    if (v.empty()) continue;
    for (std::size_t start = 0;;) {
      const std::size_t comma = v.find(',', start);
      const std::string id = v.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      Require(!id.empty(), ErrorCode::kInvalidArgument, "prev: empty id in the list (ids separated by single commas)");
      TargetInfo t;
      t.id = id;
      try {
        ValidateTargetInfo(t, /*new_id=*/false, "prev");
      } catch (const Error&) {
        throw Error(ErrorCode::kInvalidArgument, "prev: invalid exhibit id (1..256 bytes of UTF-8, no control characters)");
      }
      if (std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);
      Require(ids.size() <= kMaxPrev, ErrorCode::kInvalidArgument,
              "prev: more than " + std::to_string(kMaxPrev) + " exhibit ids");
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  return ids;
}

}  // namespace

struct Service::Impl {
  explicit Impl(ServiceOptions o)
      : a(std::move(o)), cpu(a.threads), thumbs(a.thumb_cache_mb << 20), tokens(a.token_failures_before_delay) {
    if (!a.log) a.log = DefaultLog;
    // Configuration errors first, before seconds of loading exhibits.
    if (!a.site.empty()) site = LoadSite(a.site);
    srv = MakeServer(a);
    if (a.max_inflight <= 0) a.max_inflight = 8 * a.threads;
    options = a.words ? RecognizerOptions::Words() : RecognizerOptions{};
    if (!a.words) options.probe_words = a.probe_words;
    watch_store = std::make_unique<TargetStore>(TargetStore::Open(a.db));
    ReloadAfterChange();
    // Stored quality reports (exhibits added through the admin API).
    for (const auto& [info, data] : TargetStore::Open(a.db).LoadEncodings(kQualityEncoding)) {
      Json q;
      if (TryParseJsonLimited(std::string_view(reinterpret_cast<const char*>(data.data()), data.size()), q))
        quality[info.id] = {info.added_at, q};  // else damaged: computed again on request
    }
  }

  // --- state -------------------------------------------------------------
  ServiceOptions a;
  RecognizerOptions options;
  Site site;                          // GET /api/site
  std::unique_ptr<httplib::Server> srv;  // an httplib::SSLServer with a certificate
  int listen_fd = -1;
  int port = -1;
  std::atomic<bool> stopping{false};
  std::atomic<bool> running{false}, listen_done{false}, in_run{false};
  std::atomic<ConnectionDeadline*> deadline{nullptr};  // while Run serves

  mutable std::shared_mutex mutex;  // recognitions share it; a reload takes it alone
  std::shared_ptr<Recognizer> rec;
  std::map<std::string, TargetInfo> info;
  std::map<std::string, cv::Size> size;
  std::vector<SkippedTarget> skipped;  // at the last load

  std::mutex admin_mutex;                     // one writer; also serialises reloads
  std::unique_ptr<TargetStore> watch_store;   // a connection kept open for its data_version
  std::uint64_t seen_version = 0;             // data_version of the last load (admin_mutex)

  // The state of reloads after changes by others.
  mutable std::mutex health_mutex;
  std::string reload_error;        // last failure, "" once a reload succeeds
  std::string reload_error_since;  // UTC time of the first failure in a row
  std::uint64_t reload_failures = 0, reload_failures_in_a_row = 0;

  struct CachedQuality {
    std::string added_at;
    Json report;
  };
  std::map<std::string, CachedQuality> quality;  // by id, with the added_at it belongs to
  std::mutex quality_mutex;
  std::mutex assess_mutex;  // one on-demand assessment at a time
  std::mutex db_quality_mutex;  // one database report at a time

  CpuGate cpu;
  ThumbCache thumbs;
  TokenGuard tokens;
  std::atomic<int> inflight{0};
  std::atomic<std::uint64_t> connections_cut{0}, trainings{0}, internal_errors{0}, request_seq{0};
  Metrics metrics;

  void Log(const Json& j) { a.log(Dump(j)); }

  std::size_t Size() const {
    std::shared_lock<std::shared_mutex> lock(mutex);
    return rec ? rec->size() : 0;
  }

  // --- loading -------------------------------------------------------------

  // Reloads after a change this service committed (admin_mutex held, or at
  // start): data_version is read before loading, so a commit by anyone else
  // after that point is still seen by WatchDatabase.
  void ReloadAfterChange() {
    const std::uint64_t v = watch_store->DataVersion();
    Reload();
    seen_version = v;
  }

  // Polled: reload when another connection (another replica's admin API,
  // `mvkp db`) has committed since the last load. A database that cannot be
  // loaded keeps the recogniser serving what it has, and /healthz says so.
  void WatchDatabase() {
    std::unique_lock<std::mutex> admin(admin_mutex);
    try {
      const std::uint64_t v = watch_store->DataVersion();
      if (v == seen_version) {
        std::lock_guard<std::mutex> h(health_mutex);
        if (reload_error.empty()) return;
        // A failed reload is retried at every poll until it succeeds.
      }
      Timer t;
      Reload();
      seen_version = v;
      {
        std::lock_guard<std::mutex> h(health_mutex);
        reload_error.clear();
        reload_failures_in_a_row = 0;
      }
      Log({{"event", "reloaded"}, {"reason", "database changed"}, {"exhibits", Size()}, {"ms", t.ElapsedMs()}});
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> h(health_mutex);
      if (reload_error.empty()) reload_error_since = NowUtcIso8601();
      reload_error = e.what();
      ++reload_failures;
      ++reload_failures_in_a_row;
      if (reload_failures_in_a_row == 1 || reload_failures_in_a_row % 100 == 0)
        Log({{"event", "reload failed"}, {"error", e.what()}, {"in_a_row", reload_failures_in_a_row}});
    }
  }

  // (Re)loads every exhibit: at start, and after a change. A damaged exhibit
  // is skipped and reported; the others are served.
  void Reload() {
    const TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadOnly);
    auto r = std::make_shared<Recognizer>(options);
    std::map<std::string, TargetInfo> inf;
    std::map<std::string, cv::Size> sz;
    std::vector<SkippedTarget> skip;
    LoadTargets(
        store, *r, a.db,
        [&](const TargetInfo& t, int w, int h) {
          inf[t.id] = t;
          sz[t.id] = {w, h};
        },
        &skip);
    r->ShrinkToFit();
    r->Prepare();  // build the index here, not in the first request after the swap
    for (const auto& s : skip) Log({{"event", "exhibit skipped"}, {"id", s.id}, {"error", s.error}});
    {
      std::unique_lock<std::shared_mutex> lock(mutex);
      rec.swap(r);
      info = std::move(inf);
      size = std::move(sz);
      skipped = std::move(skip);
    }
    // The old recogniser is freed once no recognition holds it; give its
    // pages back (glibc keeps freed memory in per-thread arenas, and a
    // reload per metadata edit grew RSS ~0.5 MB each in the soak).
    r.reset();
    ::malloc_trim(0);
  }

  // --- helpers -------------------------------------------------------------

  // A 5xx without internal detail; the detail goes to the log.
  void Internal(httplib::Response& res, const std::string& detail, int status = 500) {
    const std::uint64_t n = ++internal_errors;
    Log({{"event", "internal error"}, {"error", detail}, {"n", n}});
    SendError(res, status, "internal error (logged as #" + std::to_string(n) + ")");
  }

  bool Authorised(const httplib::Request& req, httplib::Response& res) {
    if (a.admin_token.empty()) {
      SendError(res, 403, "the admin API is off (start the server with an admin token)");
      return false;
    }
    if (const double wait = tokens.Blocked(req.remote_addr); wait > 0) {
      res.set_header("Retry-After", std::to_string(int(std::ceil(wait))));
      SendError(res, 429, "too many wrong tokens from this address: try again later");
      return false;
    }
    const std::string want = "Bearer " + a.admin_token;
    const std::string got = req.get_header_value("Authorization");
    // Compare in constant time over the expected length.
    unsigned diff = got.size() != want.size();
    for (std::size_t i = 0; i < want.size(); ++i) diff |= unsigned(want[i]) ^ unsigned(i < got.size() ? got[i] : 0);
    if (diff) {
      tokens.Failed(req.remote_addr);
      SendError(res, 401, "missing or wrong bearer token");
      return false;
    }
    tokens.Succeeded(req.remote_addr);
    return true;
  }

  Json Health() const {
    Json j = {{"status", "ok"}, {"exhibits", Size()}};
    Json problems = Json::array();
    {
      std::shared_lock<std::shared_mutex> lock(mutex);
      if (!skipped.empty()) {
        Json s = Json::array();
        for (const auto& k : skipped) s.push_back({{"id", k.id}, {"error", k.error}});
        j["skipped"] = s;
        problems.push_back(std::to_string(skipped.size()) + " exhibit(s) could not be loaded and are not served");
      }
    }
    {
      std::lock_guard<std::mutex> h(health_mutex);
      if (!reload_error.empty()) {
        j["reload"] = {{"ok", false},
                       {"error", reload_error},
                       {"failing_since", reload_error_since},
                       {"failures_in_a_row", reload_failures_in_a_row}};
        problems.push_back("reloading the database fails: serving the exhibits of the last good load");
      }
    }
    if (!problems.empty()) {
      j["status"] = "degraded";
      j["problems"] = problems;
    }
    return j;
  }

  std::string MetricsText() const {
    std::string out = metrics.Text();
    std::size_t skip = 0;
    {
      std::shared_lock<std::shared_mutex> lock(mutex);
      skip = skipped.size();
    }
    std::uint64_t rf = 0;
    bool failing = false;
    {
      std::lock_guard<std::mutex> h(health_mutex);
      rf = reload_failures;
      failing = !reload_error.empty();
    }
    auto gauge = [&](const char* name, const char* help, const char* type, double v) {
      out += std::string("# HELP ") + name + " " + help + "\n# TYPE " + name + " " + type + "\n" + name + " " +
             Metrics::Num(v) + "\n";
    };
    gauge("mvkp_exhibits", "Exhibits loaded.", "gauge", double(Size()));
    gauge("mvkp_exhibits_skipped", "Exhibits that could not be loaded (damaged rows).", "gauge", double(skip));
    gauge("mvkp_reload_failing", "1 while reloading the database fails.", "gauge", failing ? 1 : 0);
    gauge("mvkp_reload_failures_total", "Failed reloads.", "counter", double(rf));
    gauge("mvkp_inflight_recognitions", "Recognitions admitted.", "gauge", inflight.load());
    gauge("mvkp_connections_cut_total", "Connections cut for reading too slowly or lasting too long.", "counter",
          double(connections_cut.load()));
    gauge("mvkp_trainings_total", "Exhibits trained by the admin API.", "counter", double(trainings.load()));
    gauge("mvkp_admin_token_failures_total", "Requests with a wrong admin token.", "counter", double(tokens.total()));
    gauge("mvkp_internal_errors_total", "Answers 5xx for internal errors.", "counter", double(internal_errors.load()));
    out += thumbs.Metrics();
    return out;
  }

  // --- routes ----------------------------------------------------------------

  void Setup() {
    srv->new_task_queue = [this] {
      return new BoundedQueue(std::size_t(a.io_threads), std::size_t(4 * a.io_threads + a.max_inflight));
    };
    srv->set_payload_max_length(a.max_body_mb << 20);
    srv->set_keep_alive_max_count(20);
    srv->set_keep_alive_timeout(2);
    srv->set_read_timeout(a.timeout_s, 0);
    srv->set_write_timeout(a.timeout_s, 0);
    // No SO_REUSEPORT unless asked: a second server on the port must fail,
    // not share it. SO_REUSEADDR only lets a restart bind past TIME_WAIT.
    srv->set_socket_options([this](socket_t sock) {
      int yes = 1;
      ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
      if (a.reuse_port) ::setsockopt(sock, SOL_SOCKET, SO_REUSEPORT, &yes, sizeof(yes));
      listen_fd = int(sock);
    });
    srv->set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      t_request_start = Clock::now();
      const RouteInfo r = RouteOf(req.path);
      if (!r.allow.empty()) {
        const std::string m = req.method == "HEAD" ? "GET" : req.method;
        if ((", " + r.allow + ",").find(", " + m + ",") == std::string::npos) {
          res.set_header("Allow", r.allow);
          SendError(res, 405, req.method + " is not allowed on " + r.label + " (allowed: " + r.allow + ")");
          return httplib::Server::HandlerResponse::Handled;
        }
      }
      // A body without a length would be read until the client closes.
      if ((req.method == "POST" || req.method == "PUT") && !req.has_header("Content-Length") &&
          req.get_header_value("Transfer-Encoding").find("chunked") == std::string::npos) {
        SendError(res, 411, "a request body needs a Content-Length");
        return httplib::Server::HandlerResponse::Handled;
      }
      return httplib::Server::HandlerResponse::Unhandled;
    });
    srv->set_logger([this](const httplib::Request& req, const httplib::Response& res) {
      if (auto* d = deadline.load()) d->Idle(req.remote_addr, req.remote_port);
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t_request_start).count();
      const std::string route = RouteOf(req.path).label;
      Json line = {{"method", req.method},         {"path", req.path},          {"route", route},
                   {"status", res.status},         {"bytes_in", req.body.size()}, {"bytes_out", res.body.size()},
                   {"remote", req.remote_addr}};
      // A request that never got past its first line was not timed.
      const bool timed = !req.method.empty();
      line["ms"] = timed ? Json(ms) : Json(nullptr);
      metrics.Observe(route, res.status, timed ? ms / 1000.0 : 0.0);
      Log(line);
    });
    srv->set_exception_handler([this](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
      try {
        std::rethrow_exception(ep);
      } catch (const std::exception& e) {
        Internal(res, e.what());
      } catch (...) {
        Internal(res, "unknown exception");
      }
    });
    srv->set_error_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (!res.body.empty()) return;
      if (res.status == 404) return SendError(res, 404, "not found");
      if (res.status == 413) {
        // httplib caps form-encoded bodies far lower than the body limit.
        const bool form = req.get_header_value("Content-Type").rfind("application/x-www-form-urlencoded", 0) == 0;
        return SendError(res, 413, form ? "request body too large for a form; send the image as image/jpeg, "
                                          "image/png or multipart/form-data"
                                        : "request body larger than " + std::to_string(a.max_body_mb) + " MiB");
      }
      if (res.status == 400) return SendError(res, 400, "malformed or incomplete request");
      SendError(res, res.status, "HTTP " + std::to_string(res.status));
    });
    srv->set_default_headers({{"X-Content-Type-Options", "nosniff"}});

    // Every handler marks its connection busy (its request is read).
    auto H = [this](void (Impl::*fn)(const httplib::Request&, httplib::Response&)) {
      return [this, fn](const httplib::Request& req, httplib::Response& res) {
        if (auto* d = deadline.load()) d->Busy(req.remote_addr, req.remote_port);
        (this->*fn)(req, res);
      };
    };
    srv->Get(R"(/|/index\.html|/app\.js|/style\.css|/ui\.js|/sw\.js|/admin|/admin\.html|/admin\.js|/admin\.css)",
             H(&Impl::Static));
    srv->Get("/api/site", H(&Impl::SiteRoute));
    srv->Get("/api/site/logo", H(&Impl::SiteLogo));
    srv->Get("/healthz", H(&Impl::Healthz));
    srv->Get("/metrics", H(&Impl::MetricsRoute));
    srv->Post("/api/recognize", H(&Impl::Recognize));
    srv->Get("/api/exhibits", H(&Impl::List));
    srv->Get(R"(/api/exhibits/([^/]+)/image)", H(&Impl::Image));
    srv->Get(R"(/api/exhibits/([^/]+)/quality)", H(&Impl::Quality));
    srv->Get("/api/admin/check", H(&Impl::AdminCheck));
    srv->Get("/api/admin/quality", H(&Impl::DatabaseQuality));
    srv->Get(R"(/api/exhibits/([^/]+))", H(&Impl::GetExhibit));
    srv->Post("/api/exhibits", H(&Impl::AddExhibit));
    srv->Put(R"(/api/exhibits/([^/]+))", H(&Impl::UpdateExhibit));
    srv->Put(R"(/api/exhibits/([^/]+)/image)", H(&Impl::ReplaceImage));
    srv->Delete(R"(/api/exhibits/([^/]+))", H(&Impl::DeleteExhibit));
  }

  void Static(const httplib::Request& req, httplib::Response& res) {
    const WebAsset* w = FindWebAsset(req.path);
    if (!w) return SendError(res, 404, "not found");
    res.set_header("Cache-Control", "no-cache");
    res.set_header("Content-Security-Policy", kContentSecurityPolicy);
    res.set_header("Referrer-Policy", "same-origin");
    res.set_content(std::string(w->body), std::string(w->content_type).c_str());
  }

  void SiteRoute(const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-cache");
    res.set_content(Dump(site.ToJson()), "application/json");
  }

  void SiteLogo(const httplib::Request&, httplib::Response& res) {
    if (site.logo.empty()) return SendError(res, 404, "this site has no logo (add \"logo\" to the --site file)");
    res.set_header("Cache-Control", "no-cache");
    res.set_content(site.logo, site.logo_type.c_str());
  }

  void Healthz(const httplib::Request&, httplib::Response& res) { res.set_content(Dump(Health()), "application/json"); }

  void MetricsRoute(const httplib::Request&, httplib::Response& res) {
    res.set_content(MetricsText(), "text/plain; version=0.0.4");
  }

  void AdminCheck(const httplib::Request& req, httplib::Response& res) {
    if (Authorised(req, res)) res.status = 204;
  }

  void List(const httplib::Request&, httplib::Response& res) {
    Json list = Json::array();
    for (const auto& t : TargetStore::Open(a.db).List()) list.push_back(InfoJson(t));
    res.set_content(Dump(Json{{"exhibits", list}}), "application/json");
  }

  void GetExhibit(const httplib::Request& req, httplib::Response& res) {
    const TargetStore store = TargetStore::Open(a.db);
    const std::string id = req.matches[1];
    if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
    res.set_content(Dump(InfoJson(store.Get(id, false).info)), "application/json");
  }

  // The stored image, or with ?thumb=N a JPEG at most N px on its longest
  // side (decoded at a reduced size where JPEG allows, then kept in a
  // bounded cache). An ETag from the exhibit's size and time of addition
  // lets browsers keep it.
  void Image(const httplib::Request& req, httplib::Response& res) {
    const TargetStore store = TargetStore::Open(a.db);
    const std::string id = req.matches[1];
    if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
    int thumb = 0;
    if (req.has_param("thumb")) {
      const std::string v = req.get_param_value("thumb");
      try {
        std::size_t used = 0;
        thumb = std::stoi(v, &used);
        if (used != v.size()) thumb = -1;
      } catch (const std::exception&) {
        thumb = -1;
      }
      if (thumb < 16 || thumb > 1024) return SendError(res, 400, "thumb must be a whole number of pixels, 16 to 1024");
    }
    const TargetInfo inf = store.Get(id, false).info;
    const std::string key = id + "\n" + inf.added_at + "\n" + std::to_string(thumb);
    const bool small = thumb == 0 || std::max(inf.width, inf.height) <= thumb;
    std::optional<std::string> cached = small ? std::nullopt : thumbs.Get(key);
    std::vector<std::uint8_t> original;
    std::size_t original_size = 0;
    if (!cached) {
      original = store.Get(id, true).image;
      original_size = original.size();
      if (original.empty()) return SendError(res, 404, "exhibit has no stored image");
    }
    const std::string etag = "\"" + inf.added_at + "-" + std::to_string(thumb) + "\"";
    res.set_header("ETag", etag);
    res.set_header("Cache-Control", "no-cache");
    if (req.get_header_value("If-None-Match") == etag) {
      res.status = 304;
      return;
    }
    if (cached) return res.set_content(*cached, "image/jpeg");
    if (small) {
      const bool png = original_size > 4 && original[0] == 0x89 && original[1] == 'P';
      return res.set_content(std::string(original.begin(), original.end()), png ? "image/png" : "image/jpeg");
    }
    int reduce = 1;  // JPEG decodes at 1/2, 1/4, 1/8 for little more than the cost of reading
    while (reduce < 8 && std::max(inf.width, inf.height) / (2 * reduce) >= thumb) reduce *= 2;
    cv::Mat img;
    {
      const auto slot = cpu.Acquire();
      try {
        img = DecodeStored("the stored image of '" + id + "'", original, a.max_pixels, true, reduce);
      } catch (const Error& e) {
        return SendError(res, 422, e.what());
      }
      const double scale = double(thumb) / std::max(img.cols, img.rows);
      if (scale < 1) cv::resize(img, img, cv::Size(), scale, scale, cv::INTER_AREA);
    }
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
    std::string body(jpeg.begin(), jpeg.end());
    thumbs.Put(key, body);
    res.set_content(std::move(body), "image/jpeg");
  }

  // GET /api/exhibits/{id}/quality (admin: an assessment costs seconds).
  void Quality(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    const std::string id = req.matches[1];
    const TargetStore store = TargetStore::Open(a.db);
    if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
    const std::string added_at = store.Get(id, false).info.added_at;
    auto cached = [&](Json& out) {
      std::lock_guard<std::mutex> lock(quality_mutex);
      const auto it = quality.find(id);
      if (it == quality.end() || it->second.added_at != added_at) return false;
      out = it->second.report;
      return true;
    };
    Json q;
    bool computed = false;
    if (!cached(q)) {
      // One assessment at a time, so a page asking for many keeps at most
      // one core busy; a second request for the same id finds the first's.
      std::lock_guard<std::mutex> one(assess_mutex);
      if (!cached(q)) {
        const TargetRecord r = store.Get(id, true);
        if (r.image.empty()) return SendError(res, 404, "exhibit '" + id + "' has no stored image to assess");
        cv::Mat gray;
        try {
          // Larger than the request limit (added by `mvkp db add`): assessed
          // from a reduced decode; quality trains at 640 px anyway.
          gray = DecodeStored("the stored image of '" + id + "'", r.image, a.max_pixels, false);
        } catch (const Error& e) {
          return SendError(res, 422, e.what());
        }
        const auto slot = cpu.Acquire();
        q = QualityJson(AssessTarget(gray, QualityOptions{}), /*with_points=*/false);
        computed = true;
        std::lock_guard<std::mutex> lock(quality_mutex);
        quality[id] = {added_at, q};
      }
    }
    q["id"] = id;
    q["cached"] = !computed;
    res.set_content(Dump(q), "application/json");
  }

  // GET /api/admin/quality: `mvkp quality DB --json` for the served
  // database. Scores come from the per-exhibit cache (keyed by added_at, shared
  // with /api/exhibits/{id}/quality), so only new or replaced exhibits are
  // assessed (seconds each, one at a time, in a CPU slot); the look-alike
  // search (~0.1 s per exhibit) runs on every request.
  void DatabaseQuality(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    std::lock_guard<std::mutex> one(db_quality_mutex);
    Timer total;
    DatabaseQualityOptions o;
    o.score = false;  // below, through the cache
    o.max_pixels = a.max_pixels;
    o.name = "the database";  // answers never name the server's files
    DatabaseQualityReport r;
    {
      const auto slot = cpu.Acquire();
      r = AssessDatabase(a.db, o);
    }
    Json j = DatabaseQualityJson(r);
    j.erase("db");
    const TargetStore store = TargetStore::Open(a.db);
    int computed = 0;
    for (Json& e : j["exhibits"]) {
      const std::string id = e["id"], added_at = e["added_at"];
      {
        std::lock_guard<std::mutex> lock(quality_mutex);
        const auto it = quality.find(id);
        if (it != quality.end() && it->second.added_at == added_at) e["quality"] = it->second.report;
      }
      if (!e["quality"].is_null() || e.contains("error")) continue;
      try {
        const cv::Mat gray = DecodeStored("the stored image of '" + id + "'", store.Get(id, true).image, a.max_pixels, false);
        std::lock_guard<std::mutex> lock(assess_mutex);
        const auto slot = cpu.Acquire();
        const QualityReport q = AssessTarget(gray, QualityOptions{});
        e["quality"] = QualityJson(q, /*with_points=*/false);
        e["time_ms"]["quality"] = q.ms;
        ++computed;
        std::lock_guard<std::mutex> c(quality_mutex);
        quality[id] = {added_at, e["quality"]};
      } catch (const Error& ex) {
        e["error"] = ex.what();
      }
    }
    j["assessed_now"] = computed;
    j["time_ms"] = total.ElapsedMs();
    res.set_content(Dump(j), "application/json");
  }

  void Recognize(const httplib::Request& req, httplib::Response& res) {
    // Bounded admission: refuse at once rather than queue without end.
    if (t_overloaded || inflight.fetch_add(1) >= a.max_inflight) {
      if (!t_overloaded) inflight.fetch_sub(1);
      res.set_header("Retry-After", "1");
      return SendError(res, 503, "busy: " + std::to_string(a.max_inflight) + " requests already being served");
    }
    struct Release {
      std::atomic<int>& n;
      ~Release() { n.fetch_sub(1); }
    } release{inflight};
    Timer total;
    std::string body = req.body;
    if (req.is_multipart_form_data()) {
      if (!req.has_file("image")) return SendError(res, 400, "multipart request without an 'image' field");
      body = req.get_file_value("image").content;
    }
    if (body.empty()) return SendError(res, 400, "empty body: send a JPEG or PNG image");
    std::optional<CameraModel> cam;
    double width_m = 0;
    std::vector<std::string> prev;
    try {
      prev = ParsePrev(req);
      if (req.has_param("fx")) {
        CameraModel c;
        const double fx = Param(req, "fx", 0), fy = Param(req, "fy", fx);
        if (!(fx > 0 && fy > 0)) return SendError(res, 400, "fx and fy must be positive");
        c.K = cv::Matx33d(fx, 0, Param(req, "cx", -1), 0, fy, Param(req, "cy", -1), 0, 0, 1);
        c.dist = cv::Mat::zeros(1, 5, CV_64F);
        cam = c;
        width_m = Param(req, "width_m", 0);
        if (width_m < 0) return SendError(res, 400, "width_m must be positive");
      }
    } catch (const Error& e) {
      return SendError(res, 400, e.what());
    }
    const auto slot = cpu.Acquire();
    Timer decode;
    cv::Mat gray;
    ImageLimits lim;
    lim.max_pixels = a.max_pixels;
    lim.max_file_bytes = std::int64_t(a.max_body_mb) << 20;
    // A phone's 12 or 48 MP JPEG is decoded at 1/2 to 1/8 of its size (DCT
    // scaling), keeping 1.5x the recogniser's working size, and the answer is
    // mapped back to the photo's pixels. With a camera model (pose), in full.
    cv::Matx33d to_full = cv::Matx33d::eye();
    cv::Size full_size;
    try {
      ReducedImage dec = DecodeImageGrayReduced("request body", std::vector<std::uint8_t>(body.begin(), body.end()),
                                                cam ? 0 : kRecognizeMinSide, lim);
      gray = dec.gray;
      to_full = dec.ToFull();
      full_size = dec.full;
    } catch (const Error& e) {
      const bool too_big = std::string(e.what()).find("limit") != std::string::npos ||
                           std::string(e.what()).find("large") != std::string::npos;
      return SendError(res, too_big ? 413 : 400, e.what());
    }
    if (cam) {
      if (cam->K(0, 2) < 0) cam->K(0, 2) = gray.cols / 2.0;
      if (cam->K(1, 2) < 0) cam->K(1, 2) = gray.rows / 2.0;
      cam->image_size = gray.size();
    }
    std::shared_lock<std::shared_mutex> lock(mutex);
    // The full search finds every exhibit in view, new ones too, from one
    // set of frame features (verifying as many more candidates as exhibits
    // are known to be in view, so that those leave room for new ones); then
    // each exhibit the client saw last time that it missed gets a focused
    // check of its own (temporal focus, thesis §6.3.1: more sensitive, but
    // one feature extraction per id). Ids no longer stored are ignored.
    const auto known = std::count_if(prev.begin(), prev.end(), [&](const std::string& id) { return rec->Contains(id); });
    RecognitionResult r = rec->Recognize(gray, rec->options().max_candidates + int(known));
    std::string mode = "full";
    for (const std::string& id : prev) {
      if (!rec->Contains(id)) continue;
      if (std::any_of(r.found.begin(), r.found.end(), [&](const Recognition& x) { return x.id == id; })) continue;
      const RecognitionResult one = rec->RecognizeOne(gray, id);
      mode = "full+focus";
      r.detect_ms += one.detect_ms;
      r.describe_ms += one.describe_ms;
      r.search_ms += one.search_ms;
      r.verify_ms += one.verify_ms;
      r.found.insert(r.found.end(), one.found.begin(), one.found.end());
    }
    if (to_full != cv::Matx33d::eye())
      for (auto& f : r.found) {
        f.homography = to_full * f.homography;
        for (auto& p : f.outline) {
          const cv::Vec3d q = to_full * cv::Vec3d(p.x, p.y, 1);
          p = cv::Point2f(float(q[0]), float(q[1]));
        }
      }
    std::stable_sort(r.found.begin(), r.found.end(),
                     [](const Recognition& x, const Recognition& y) { return x.inliers > y.inliers; });
    Json found = Json::array();
    for (const auto& f : r.found) {
      const TargetInfo& t = info.at(f.id);
      Json x = RecognitionJson(f, t.title);
      x["artist"] = t.artist;
      x["year"] = t.year;
      x["url"] = t.url;
      if (cam) {
        double w = width_m;
        Json meta;
        if (TryParseJsonLimited(t.meta, meta, MetaJsonLimits()) && meta.is_object() && meta.contains("width_m") &&
            meta["width_m"].is_number())
          w = meta["width_m"].get<double>();
        if (w > 0) {
          const cv::Size s = size.at(f.id);
          const Pose p = EstimatePose(f.homography, s.width, s.height, w, *cam);
          if (p.ok) x["pose"] = PoseJson(p);
        }
      }
      found.push_back(x);
    }
    res.set_content(Dump(Json{{"found", found},
                              {"mode", mode},
                              {"width", full_size.width},
                              {"height", full_size.height},
                              {"time_ms", {{"recognize", r.total_ms()}, {"total", total.ElapsedMs()}}}}),
                    "application/json");
  }

  void AddExhibit(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    if (t_overloaded) {
      res.set_header("Retry-After", "1");
      return SendError(res, 503, "busy: try again");
    }
    if (!req.is_multipart_form_data() || !req.has_file("image") || !req.has_file("id"))
      return SendError(res, 400, "expected multipart fields 'image' and 'id' (and optional title, artist, year, url, meta)");
    for (const auto& [name, f] : req.files) {
      static const std::set<std::string> kFields = {"image", "id", "title", "artist", "year", "url", "meta",
                                                    "allow_duplicate"};
      if (!kFields.count(name)) return SendError(res, 400, "unknown field '" + name + "'");
    }
    auto field = [&](const char* k) { return req.has_file(k) ? req.get_file_value(k).content : std::string(); };
    TargetInfo inf;
    inf.id = field("id");
    inf.title = field("title");
    inf.artist = field("artist");
    inf.year = field("year");
    inf.url = field("url");
    inf.meta = req.has_file("meta") ? field("meta") : "{}";
    // Everything but the image is checked before seconds of training.
    try {
      ValidateTargetInfo(inf, /*new_id=*/true, "exhibit");
    } catch (const Error& e) {
      return SendError(res, 400, e.what());
    }
    const std::string img = field("image");
    Timer total;
    double train_ms = 0, quality_ms = 0;
    Json q;
    std::unique_lock<std::mutex> admin(admin_mutex);  // one writer
    try {
      TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
      if (store.Contains(inf.id)) return SendError(res, 409, "exhibit '" + inf.id + "' already exists");
      TargetRecord r;
      if (!Train(inf, img, field("allow_duplicate") == "1", r, q, train_ms, quality_ms, res)) return;
      store.Add(r);  // one transaction
    } catch (const std::exception& e) {
      return Internal(res, std::string("admin add: ") + e.what());
    }
    Timer reload;
    ReloadAfterChange();
    const double reload_ms = reload.ElapsedMs();
    const TargetInfo added = TargetStore::Open(a.db).Get(inf.id, false).info;
    {
      std::lock_guard<std::mutex> lock(quality_mutex);
      quality[inf.id] = {added.added_at, q};
    }
    Json out = InfoJson(added);
    out["quality"] = q;
    out["time_ms"] = {{"train", train_ms}, {"quality", quality_ms}, {"reload", reload_ms}, {"total", total.ElapsedMs()}};
    res.status = 201;
    res.set_content(Dump(out), "application/json");
  }

  // Decodes and trains an exhibit's image with its quality report (admin
  // add and replace; admin_mutex held). A bad image or one training refuses
  // gets 400 and false; an image that shows another exhibit (unless
  // `allow_duplicate`) 409 with "duplicates"; internal failures throw.
  bool Train(const TargetInfo& inf, const std::string& img, bool allow_duplicate, TargetRecord& r, Json& q,
             double& train_ms, double& quality_ms, httplib::Response& res) {
    cv::Mat gray;
    try {
      ImageLimits lim;
      lim.max_pixels = a.max_pixels;
      gray = DecodeImageGray("image", std::vector<std::uint8_t>(img.begin(), img.end()), lim);
    } catch (const Error& e) {
      SendError(res, 400, e.what());
      return false;
    }
    const auto slot = cpu.Acquire();
    if (!allow_duplicate) {
      std::vector<DuplicateOf> dups;
      {
        std::shared_lock<std::shared_mutex> lock(mutex);
        dups = FindDuplicates(*rec, gray);
      }
      std::erase_if(dups, [&](const DuplicateOf& d) { return d.id == inf.id; });  // a new photo of itself
      if (!dups.empty()) {
        Json list = Json::array();
        for (const auto& d : dups) list.push_back({{"id", d.id}, {"inliers", d.inliers}});
        res.status = 409;
        res.set_content(Dump(Json{{"error", "the image " + DescribeDuplicates(dups) +
                                                ", already an exhibit: two copies of one picture take each other's "
                                                "votes and neither is found (send allow_duplicate=1 to add it anyway)"},
                                  {"duplicates", list}}),
                        "application/json");
        return false;
      }
    }
    ++trainings;
    // The quality assessment (the longer job) runs beside the training.
    auto assessed = std::async(std::launch::async, [&gray] { return AssessTarget(gray, QualityOptions{}); });
    Timer train;
    try {
      r = MakeTargetRecord(inf, std::vector<std::uint8_t>(img.begin(), img.end()), gray, DbTrainDefaults(), "image");
    } catch (const Error& e) {
      assessed.wait();
      if (e.code() == ErrorCode::kIo) throw;
      SendError(res, 400, e.what());
      return false;
    }
    train_ms = train.ElapsedMs();
    const QualityReport report = assessed.get();
    quality_ms = report.ms;
    q = QualityJson(report, /*with_points=*/false);
    const std::string qs = Dump(q);
    r.encodings.push_back({kQualityEncoding, std::vector<std::uint8_t>(qs.begin(), qs.end())});
    return true;
  }

  // PUT /api/exhibits/{id}/image (admin): a new photo (the body, image/jpeg
  // or image/png, or multipart field "image"), checked and trained as an
  // add's; id and metadata stay. A refused image or a failed training keeps
  // the old image and model (one transaction replaces them).
  void ReplaceImage(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    if (t_overloaded) {
      res.set_header("Retry-After", "1");
      return SendError(res, 503, "busy: try again");
    }
    const std::string id = req.matches[1];
    const bool form = req.is_multipart_form_data();
    const std::string img = !form ? req.body : req.has_file("image") ? req.get_file_value("image").content : "";
    if (img.empty())
      return SendError(res, 400, "expected the new image as the body (image/jpeg or image/png) or multipart field 'image'");
    Timer total;
    double train_ms = 0, quality_ms = 0;
    Json q;
    std::unique_lock<std::mutex> admin(admin_mutex);  // one writer
    try {
      TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
      if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
      TargetRecord r;
      const bool allow = req.get_param_value("allow_duplicate") == "1" ||
                         (form && req.has_file("allow_duplicate") && req.get_file_value("allow_duplicate").content == "1");
      if (!Train(store.Get(id, false).info, img, allow, r, q, train_ms, quality_ms, res)) return;
      if (!store.ReplaceImage(r)) return SendError(res, 404, "no exhibit '" + id + "'");
    } catch (const std::exception& e) {
      return Internal(res, std::string("admin replace image: ") + e.what());
    }
    thumbs.Clear();  // keyed by added_at, which has whole seconds: a replace within one must not show the old photo
    ReloadAfterChange();
    const TargetInfo now = TargetStore::Open(a.db).Get(id, false).info;
    {
      std::lock_guard<std::mutex> lock(quality_mutex);
      quality[id] = {now.added_at, q};
    }
    Json out = InfoJson(now);
    out["quality"] = q;
    out["time_ms"] = {{"train", train_ms}, {"quality", quality_ms}, {"total", total.ElapsedMs()}};
    res.set_content(Dump(out), "application/json");
  }

  void UpdateExhibit(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    const std::string id = req.matches[1];
    Json j;
    try {
      JsonLimits lim = MetaJsonLimits();
      lim.max_depth += 1;  // the body object holds meta
      lim.max_bytes = kMaxPutBytes;
      j = ParseJsonLimited(req.body, lim, "request body");
    } catch (const Error& e) {
      return SendError(res, 400, e.what());
    }
    if (!j.is_object()) return SendError(res, 400, "body must be a JSON object");
    for (const auto& [k, v] : j.items()) {
      static const std::set<std::string> kFields = {"id", "title", "artist", "year", "url", "meta"};
      if (!kFields.count(k)) return SendError(res, 400, "unknown field '" + k + "' (fields: title, artist, year, url, meta)");
    }
    if (j.contains("id") && !(j["id"].is_string() && j["id"].get<std::string>() == id))
      return SendError(res, 400, "id cannot be changed (it is the exhibit's address): delete and add instead");
    std::unique_lock<std::mutex> admin(admin_mutex);
    TargetInfo updated;
    try {
      TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
      if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
      TargetInfo inf = store.Get(id, false).info;
      auto str = [&](const char* k, std::string& dst) {
        if (!j.contains(k)) return;
        if (!j[k].is_string()) throw Error(ErrorCode::kInvalidArgument, std::string(k) + " must be a string");
        dst = j[k].get<std::string>();
      };
      try {
        str("title", inf.title);
        str("artist", inf.artist);
        str("year", inf.year);
        str("url", inf.url);
        if (j.contains("meta")) {
          if (!j["meta"].is_object()) throw Error(ErrorCode::kInvalidArgument, "meta must be a JSON object");
          inf.meta = Dump(j["meta"]);
        }
        ValidateTargetInfo(inf, /*new_id=*/false, "exhibit");
      } catch (const Error& e) {
        return SendError(res, 400, e.what());
      }
      store.UpdateInfo(inf);
      updated = TargetStore::Open(a.db).Get(id, false).info;
    } catch (const std::exception& e) {
      return Internal(res, std::string("admin update: ") + e.what());
    }
    // Metadata only: the recogniser stays; recognitions see the new text at once.
    {
      std::unique_lock<std::shared_mutex> lock(mutex);
      const auto it = info.find(updated.id);
      if (it != info.end()) it->second = updated;
    }
    res.set_content(Dump(InfoJson(updated)), "application/json");
  }

  void DeleteExhibit(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    const std::string id = req.matches[1];
    std::unique_lock<std::mutex> admin(admin_mutex);
    try {
      TargetStore store = TargetStore::Open(a.db, TargetStore::Mode::kReadWrite);
      if (!store.Remove(id)) return SendError(res, 404, "no exhibit '" + id + "'");
    } catch (const std::exception& e) {
      return Internal(res, std::string("admin delete: ") + e.what());
    }
    {
      std::lock_guard<std::mutex> lock(quality_mutex);
      quality.erase(id);
    }
    ReloadAfterChange();
    res.status = 204;
  }
};

Service::Service(ServiceOptions options) {
  options.Check();  // before any member sized by the options exists
  impl_ = std::make_unique<Impl>(std::move(options));
  impl_->Setup();
}

Service::~Service() {
  // Run may still be serving in another thread: stop it and wait, so no
  // handler outlives the state it uses.
  Stop();
  while (impl_->in_run) std::this_thread::sleep_for(std::chrono::milliseconds(10));
}

int Service::Bind() {
  Impl& m = *impl_;
  if (m.port > 0) return m.port;
  int port = -1;
  if (m.a.port == 0) port = m.srv->bind_to_any_port(m.a.host);
  else if (m.srv->bind_to_port(m.a.host, m.a.port)) port = m.a.port;
  Require(port > 0, ErrorCode::kIo,
          "cannot listen on " + m.a.host + ":" + std::to_string(m.a.port) + " (in use by another process, or not allowed)");
  // httplib listens with a backlog of 5: a burst of phones would be refused.
  // listen() again on the bound socket sets the queue it keeps.
  if (m.listen_fd >= 0) ::listen(m.listen_fd, m.a.backlog);
  m.port = port;
  return port;
}

int Service::port() const { return impl_->port; }

void Service::Stop() { impl_->stopping = true; }

void Service::Run() {
  Impl& m = *impl_;
  m.in_run = true;
  struct Leave {
    std::atomic<bool>& f;
    ~Leave() { f = false; }
  } leave{m.in_run};
  Bind();
  // Stop() only raises a flag (it may come from a signal handler's thread);
  // this thread stops the server, again until listening has ended (a stop
  // before httplib starts listening would be lost).
  std::thread stopper([&m] {
    while (!m.stopping) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    while (m.running || !m.listen_done) {
      m.srv->stop();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  std::thread db_watch([&m] {
    // Replicas share one database: each picks up what others (or `mvkp db`)
    // commit, within watch_s seconds.
    auto next = Clock::now() + std::chrono::milliseconds(std::int64_t(m.a.watch_s * 1000));
    while (!m.stopping && m.a.watch_s > 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (Clock::now() < next) continue;
      next = Clock::now() + std::chrono::milliseconds(std::int64_t(m.a.watch_s * 1000));
      m.WatchDatabase();
    }
  });
  m.Log({{"event", "listening"},
         {"host", m.a.host},
         {"port", m.port},
         {"exhibits", m.Size()},
         {"skipped", m.skipped.size()},
         {"threads", m.a.threads},
         {"io_threads", m.a.io_threads},
         {"admin", !m.a.admin_token.empty()},
         {"https", !m.a.cert.empty()},
         {"site", m.site.name},
         {"search", m.a.words ? "words" : "exact"}});
  {
    ConnectionDeadline deadline(m.port, std::chrono::milliseconds(std::int64_t(m.a.max_connection_s * 1000)),
                                std::chrono::milliseconds(std::int64_t(std::min(m.a.read_deadline_s, m.a.max_connection_s) * 1000)),
                                std::chrono::milliseconds(250), std::chrono::seconds(5), &m.connections_cut);
    m.deadline = &deadline;
    m.running = true;
    m.srv->listen_after_bind();
    m.running = false;
    m.listen_done = true;
    m.deadline = nullptr;
  }
  m.stopping = true;
  stopper.join();
  db_watch.join();
  m.Log({{"event", "stopped"}});
}

}  // namespace mvkp::serve
