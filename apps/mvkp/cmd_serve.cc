// mvkp serve DB: the museum guide's server (issue 7, thesis §6.3.2). It
// recognises frames sent by phones and holds the exhibits' information.
//
//   POST /api/recognize[?prev=ID&fx=&fy=&cx=&cy=&width_m=]  JPEG/PNG body or
//        multipart field "image" -> found exhibits (id, title, artist, year,
//        url, outline, homography, inliers, score[, pose]) and timings
//   GET  /api/exhibits, /api/exhibits/{id}, /api/exhibits/{id}/image
//        [?thumb=N: a JPEG at most N px on its longest side, 16..1024]
//   POST /api/exhibits (multipart: image, id, title, artist, year, url, meta)
//        -> 201 with the exhibit and its target quality ("quality"),
//   PUT  /api/exhibits/{id} (JSON metadata), DELETE /api/exhibits/{id},
//   GET  /api/exhibits/{id}/quality (the report of `mvkp quality`),
//   GET  /api/admin/check (204: the token is right):
//        admin, "Authorization: Bearer TOKEN" with the token read from
//        --admin-token-file at start; without that file the admin API is off
//   GET  /healthz, /metrics (Prometheus text)
//   GET  /, /admin: the web client and the admin page (web/, linked in)
//
// Target quality (AssessTarget, ~2 s of one core at the default 120 test
// views) is computed when the admin API adds an exhibit, concurrently with
// its training, and stored beside the model (encoding "quality", JSON), so it
// survives restarts; for exhibits added otherwise (mvkp db add / import) it is
// computed on the first request, one at a time, and kept in memory.
//
// Limits: body size, image pixels, read/write timeouts, and at most
// --max-inflight recognitions at once (more get 503 at once, not a queue).
// Errors are JSON {"error": "..."} with a 4xx/5xx status. One JSON log line
// per request on stderr. SIGTERM/SIGINT stop accepting and finish in-flight
// requests.
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.h"
#include "db_load.h"
#include "mvkp/core/atomic_file.h"
#include "mvkp/core/error.h"
#include "mvkp/core/image_io.h"
#include "mvkp/core/timer.h"
#include "mvkp/db/target_store.h"
#include "mvkp/model/model.h"
#include "mvkp/pose/pose.h"
#include "mvkp/quality/quality.h"
#include "mvkp/recognize/recognizer.h"
#include "mvkp/train/trainer.h"
#include "output.h"
#include "pose_cli.h"
#include "conn_deadline.h"
#include "web_assets.h"

namespace mvkp::cli {
namespace {

struct ServeArgs {
  std::string db, host = "127.0.0.1", token_file;
  int port = 8080, threads = 2, max_inflight = 0;  // 0: 8 x threads
  std::size_t max_body_mb = 10;
  std::int64_t max_pixels = 12'000'000;
  int timeout_s = 10;
  double max_connection_s = 30;  // total per connection (slow clients), ConnectionDeadline
  bool words = false;
  int probe_words = RecognizerOptions{}.probe_words;
  double watch_s = 2;  // database change polling period (0: off)
};

using Json = nlohmann::json;

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
  std::string Text(std::size_t targets, int inflight) const {
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
    out += "# HELP mvkp_exhibits Exhibits loaded.\n# TYPE mvkp_exhibits gauge\nmvkp_exhibits " + std::to_string(targets) + "\n";
    out += "# HELP mvkp_inflight_recognitions Recognitions running.\n# TYPE mvkp_inflight_recognitions gauge\n"
           "mvkp_inflight_recognitions " + std::to_string(inflight) + "\n";
    return out;
  }

 private:
  static std::string Num(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }
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

// JSON text; invalid UTF-8 in stored strings becomes U+FFFD instead of an exception.
std::string Dump(const Json& j) { return j.dump(-1, ' ', false, Json::error_handler_t::replace); }

void SendError(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(Dump(Json{{"error", message}}), "application/json");
}

Json InfoJson(const TargetInfo& t) {
  Json meta = Json::object();
  try {
    meta = Json::parse(t.meta);
  } catch (const std::exception&) {
  }
  return {{"id", t.id},       {"title", t.title}, {"artist", t.artist}, {"year", t.year},       {"url", t.url},
          {"meta", meta},     {"width", t.width}, {"height", t.height}, {"added_at", t.added_at}};
}

// The route label for metrics and logs (ids replaced, so labels stay few).
std::string RouteOf(const httplib::Request& req) {
  const std::string& p = req.path;
  auto ends = [&](const std::string& tail) {
    return p.size() > tail.size() && p.compare(p.size() - tail.size(), tail.size(), tail) == 0;
  };
  if (p.rfind("/api/exhibits/", 0) == 0)
    return ends("/image") ? "/api/exhibits/{id}/image" : ends("/quality") ? "/api/exhibits/{id}/quality" : "/api/exhibits/{id}";
  if (p == "/api/recognize" || p == "/api/exhibits" || p == "/api/admin/check" || p == "/healthz" || p == "/metrics") return p;
  if (p == "/admin" || p == "/admin.js" || p == "/admin.css") return "/admin";
  return "other";
}

// The kind under which the admin API stores an exhibit's quality report
// (QualityJson without the points) beside its model.
constexpr const char* kQualityEncoding = "quality";

// The static pages load only their own scripts, styles and images (the
// client's photo preview is a blob: URL), are never framed, and their
// types are not sniffed.
constexpr const char* kContentSecurityPolicy =
    "default-src 'self'; img-src 'self' blob: data:; media-src 'self' blob: mediastream:; object-src 'none'; "
    "base-uri 'none'; frame-ancestors 'none'; form-action 'self'";

std::atomic<bool> g_stop{false};
thread_local bool t_overloaded = false;  // this connection came over the bound: answer 503

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
thread_local std::chrono::steady_clock::time_point t_request_start;  // set before routing, read by the logger
extern "C" void OnSignal(int) { g_stop = true; }

class GuideServer {
 public:
  explicit GuideServer(ServeArgs a) : a_(std::move(a)) {
    if (!a_.token_file.empty()) {
      const auto bytes = ReadFileBytes(a_.token_file, 4096);
      token_.assign(bytes.begin(), bytes.end());
      while (!token_.empty() && (token_.back() == '\n' || token_.back() == '\r' || token_.back() == ' ')) token_.pop_back();
      Require(token_.size() >= 16, ErrorCode::kInvalidArgument,
              a_.token_file + ": admin token must be at least 16 characters");
    }
    // Enough for a page loading thumbnails on keep-alive beside a few phones;
    // at ~12 ms a frame the deepest queue waits ~50 ms per thread.
    if (a_.max_inflight <= 0) a_.max_inflight = 8 * a_.threads;
    options_ = a_.words ? RecognizerOptions::Words() : RecognizerOptions{};
    if (!a_.words) options_.probe_words = a_.probe_words;
    watch_store_ = std::make_unique<TargetStore>(TargetStore::Open(a_.db));
    ReloadAfterChange();
    // Stored quality reports (exhibits added through the admin API).
    for (const auto& [info, data] : TargetStore::Open(a_.db).LoadEncodings(kQualityEncoding)) {
      try {
        quality_[info.id] = {info.added_at, Json::parse(data.begin(), data.end())};
      } catch (const std::exception&) {
        // damaged: computed again on request
      }
    }
  }

  int Run() {
    httplib::Server srv;
    srv.new_task_queue = [this] { return new BoundedQueue(std::size_t(a_.threads), std::size_t(a_.max_inflight)); };
    srv.set_payload_max_length(a_.max_body_mb << 20);
    // A worker serves one connection at a time: short keep-alive keeps a few
    // busy clients from holding every worker while others queue.
    srv.set_keep_alive_max_count(2);
    srv.set_keep_alive_timeout(1);
    srv.set_read_timeout(a_.timeout_s, 0);
    srv.set_write_timeout(a_.timeout_s, 0);
    srv.set_pre_routing_handler([](const httplib::Request&, httplib::Response&) {
      t_request_start = std::chrono::steady_clock::now();
      return httplib::Server::HandlerResponse::Unhandled;
    });
    srv.set_logger([this](const httplib::Request& req, const httplib::Response& res) { Log(req, res); });
    srv.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
      try {
        std::rethrow_exception(ep);
      } catch (const std::exception& e) {
        SendError(res, 500, e.what());
      } catch (...) {
        SendError(res, 500, "internal error");
      }
    });
    srv.set_error_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (!res.body.empty()) return;
      if (res.status == 404) return SendError(res, 404, "not found");
      if (res.status == 413) {
        // httplib caps form-encoded bodies far lower than --max-body-mb.
        const bool form = req.get_header_value("Content-Type").rfind("application/x-www-form-urlencoded", 0) == 0;
        return SendError(res, 413, form ? "request body too large for a form; send the image as image/jpeg, "
                                          "image/png or multipart/form-data"
                                        : "request body larger than " + std::to_string(a_.max_body_mb) + " MiB");
      }
      SendError(res, res.status, "HTTP " + std::to_string(res.status));
    });
    srv.set_default_headers({{"X-Content-Type-Options", "nosniff"}});
    // The web client (phone-first, plain HTML/JS) at "/", the admin page at "/admin".
    srv.Get(R"(/|/index\.html|/app\.js|/style\.css|/admin|/admin\.html|/admin\.js|/admin\.css)",
            [](const httplib::Request& req, httplib::Response& res) {
              const WebAsset* w = FindWebAsset(req.path);
              res.set_header("Cache-Control", "no-cache");
              res.set_header("Content-Security-Policy", kContentSecurityPolicy);
              res.set_header("Referrer-Policy", "same-origin");
              res.set_content(std::string(w->body), std::string(w->content_type).c_str());
            });
    srv.Get("/healthz", [this](const httplib::Request&, httplib::Response& res) {
      res.set_content(Dump(Json{{"status", "ok"}, {"exhibits", Size()}}), "application/json");
    });
    srv.Get("/metrics", [this](const httplib::Request&, httplib::Response& res) {
      std::string text = metrics_.Text(Size(), inflight_.load());
      text += "# HELP mvkp_connections_cut_total Connections cut for lasting over --max-connection-s.\n"
              "# TYPE mvkp_connections_cut_total counter\nmvkp_connections_cut_total " +
              std::to_string(connections_cut_.load()) + "\n";
      res.set_content(text, "text/plain; version=0.0.4");
    });
    srv.Post("/api/recognize", [this](const httplib::Request& req, httplib::Response& res) { Recognize(req, res); });
    srv.Get("/api/exhibits", [this](const httplib::Request&, httplib::Response& res) {
      Json list = Json::array();
      for (const auto& t : TargetStore::Open(a_.db).List()) list.push_back(InfoJson(t));
      res.set_content(Dump(Json{{"exhibits", list}}), "application/json");
    });
    srv.Get(R"(/api/exhibits/([^/]+)/image)", [this](const httplib::Request& req, httplib::Response& res) { Image(req, res); });
    srv.Get(R"(/api/exhibits/([^/]+)/quality)", [this](const httplib::Request& req, httplib::Response& res) { Quality(req, res); });
    srv.Get("/api/admin/check", [this](const httplib::Request& req, httplib::Response& res) {
      if (Authorised(req, res)) res.status = 204;
    });
    srv.Get(R"(/api/exhibits/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
      const TargetStore store = TargetStore::Open(a_.db);
      if (!store.Contains(req.matches[1])) return SendError(res, 404, "no exhibit '" + std::string(req.matches[1]) + "'");
      res.set_content(Dump(InfoJson(store.Get(req.matches[1], false).info)), "application/json");
    });
    srv.Post("/api/exhibits", [this](const httplib::Request& req, httplib::Response& res) { AddExhibit(req, res); });
    srv.Put(R"(/api/exhibits/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) { UpdateExhibit(req, res); });
    srv.Delete(R"(/api/exhibits/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) { DeleteExhibit(req, res); });

    if (a_.port == 0) a_.port = srv.bind_to_any_port(a_.host);
    else if (!srv.bind_to_port(a_.host, a_.port)) a_.port = -1;
    Require(a_.port > 0, ErrorCode::kIo, "cannot listen on " + a_.host + " (port in use or not allowed)");
    std::signal(SIGTERM, OnSignal);
    std::signal(SIGINT, OnSignal);
    std::thread watcher([&srv] {
      while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      srv.stop();
    });
    // Replicas share one database: each picks up what others (or `mvkp db`)
    // commit, within --watch-db seconds.
    std::thread db_watch([this] {
      auto next = std::chrono::steady_clock::now();
      while (!g_stop && a_.watch_s > 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        if (std::chrono::steady_clock::now() < next) continue;
        next = std::chrono::steady_clock::now() + std::chrono::milliseconds(std::int64_t(a_.watch_s * 1000));
        WatchDatabase();
      }
    });
    std::fprintf(stderr, "%s\n",
                 Json{{"event", "listening"}, {"host", a_.host}, {"port", a_.port}, {"exhibits", Size()},
                      {"threads", a_.threads}, {"admin", !token_.empty()}, {"search", a_.words ? "words" : "exact"}}
                     .dump()
                     .c_str());
    {
      ConnectionDeadline deadline(a_.port, std::chrono::milliseconds(std::int64_t(a_.max_connection_s * 1000)),
                                  std::chrono::milliseconds(250), std::chrono::seconds(5), &connections_cut_);
      srv.listen_after_bind();
    }
    g_stop = true;
    watcher.join();
    db_watch.join();
    std::fprintf(stderr, "%s\n", Json{{"event", "stopped"}}.dump().c_str());
    return 0;
  }

 private:
  std::size_t Size() const {
    std::shared_lock<std::shared_mutex> lock(mutex_);
    return rec_ ? rec_->size() : 0;
  }

  // Reloads after a change this server committed (admin_mutex_ held, or at
  // start): the database's data_version is read before loading, so a commit
  // by anyone else after that point is still seen by WatchDatabase.
  void ReloadAfterChange() {
    const std::uint64_t v = watch_store_->DataVersion();
    Reload();
    seen_version_ = v;
  }

  // Polled by the db_watch thread: reload when another connection (another
  // replica's admin API, `mvkp db`) has committed since the last load. A
  // database that cannot be loaded keeps the recogniser serving what it has.
  void WatchDatabase() {
    std::unique_lock<std::mutex> admin(admin_mutex_);
    try {
      const std::uint64_t v = watch_store_->DataVersion();
      if (v == seen_version_) return;
      Timer t;
      Reload();
      seen_version_ = v;
      std::fprintf(stderr, "%s\n",
                   Json{{"event", "reloaded"}, {"reason", "database changed"}, {"exhibits", Size()}, {"ms", t.ElapsedMs()}}
                       .dump()
                       .c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", Dump(Json{{"event", "reload failed"}, {"error", e.what()}}).c_str());
    }
  }

  // (Re)loads every exhibit: at start, and after a change.
  void Reload() {
    const TargetStore store = TargetStore::Open(a_.db, TargetStore::Mode::kReadOnly);
    auto rec = std::make_shared<Recognizer>(options_);
    std::map<std::string, TargetInfo> info;
    std::map<std::string, cv::Size> size;
    LoadTargets(store, *rec, a_.db, [&](const TargetInfo& t, int w, int h) {
      info[t.id] = t;
      size[t.id] = {w, h};
    });
    rec->ShrinkToFit();
    rec->Prepare();  // build the index here, not in the first request after the swap
    std::unique_lock<std::shared_mutex> lock(mutex_);
    rec_ = std::move(rec);
    info_ = std::move(info);
    size_ = std::move(size);
  }

  // The stored image, or with ?thumb=N a JPEG at most N px on its longest
  // side (decoded at a reduced size where JPEG allows). An ETag from the
  // exhibit's size and time of addition lets browsers keep it.
  void Image(const httplib::Request& req, httplib::Response& res) const {
    const TargetStore store = TargetStore::Open(a_.db);
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
    const TargetRecord r = store.Get(id, true);
    if (r.image.empty()) return SendError(res, 404, "exhibit has no stored image");
    const std::string etag = "\"" + std::to_string(r.image.size()) + "-" + r.info.added_at + "-" + std::to_string(thumb) + "\"";
    res.set_header("ETag", etag);
    res.set_header("Cache-Control", "no-cache");
    if (req.get_header_value("If-None-Match") == etag) {
      res.status = 304;
      return;
    }
    const bool png = r.image.size() > 4 && r.image[0] == 0x89 && r.image[1] == 'P';
    if (thumb == 0 || std::max(r.info.width, r.info.height) <= thumb) {
      res.set_content(std::string(r.image.begin(), r.image.end()), png ? "image/png" : "image/jpeg");
      return;
    }
    int reduce = 1;  // JPEG decodes at 1/2, 1/4, 1/8 for little more than the cost of reading
    while (reduce < 8 && std::max(r.info.width, r.info.height) / (2 * reduce) >= thumb) reduce *= 2;
    const int flags = reduce == 8   ? cv::IMREAD_REDUCED_COLOR_8
                      : reduce == 4 ? cv::IMREAD_REDUCED_COLOR_4
                      : reduce == 2 ? cv::IMREAD_REDUCED_COLOR_2
                                    : cv::IMREAD_COLOR;
    cv::Mat img = cv::imdecode(r.image, flags);
    if (img.empty()) return SendError(res, 500, "cannot decode the stored image of '" + id + "'");
    const double scale = double(thumb) / std::max(img.cols, img.rows);
    if (scale < 1) cv::resize(img, img, cv::Size(), scale, scale, cv::INTER_AREA);
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
    res.set_content(std::string(jpeg.begin(), jpeg.end()), "image/jpeg");
  }

  // GET /api/exhibits/{id}/quality (admin: an assessment costs seconds).
  void Quality(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    const std::string id = req.matches[1];
    const TargetStore store = TargetStore::Open(a_.db);
    if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
    const std::string added_at = store.Get(id, false).info.added_at;
    auto cached = [&](Json& out) {
      std::lock_guard<std::mutex> lock(quality_mutex_);
      const auto it = quality_.find(id);
      if (it == quality_.end() || it->second.added_at != added_at) return false;
      out = it->second.report;
      return true;
    };
    Json q;
    bool computed = false;
    if (!cached(q)) {
      // One assessment at a time, so a page asking for many keeps at most
      // one core busy; a second request for the same id finds the first's.
      std::lock_guard<std::mutex> one(assess_mutex_);
      if (!cached(q)) {
        const TargetRecord r = store.Get(id, true);
        if (r.image.empty()) return SendError(res, 404, "exhibit '" + id + "' has no stored image to assess");
        ImageLimits lim;
        lim.max_pixels = a_.max_pixels;
        cv::Mat gray;
        try {
          gray = DecodeImageGray("stored image of '" + id + "'", r.image, lim);
        } catch (const Error& e) {
          return SendError(res, 500, e.what());
        }
        q = QualityJson(AssessTarget(gray, QualityOptions{}), /*with_points=*/false);
        computed = true;
        std::lock_guard<std::mutex> lock(quality_mutex_);
        quality_[id] = {added_at, q};
      }
    }
    q["id"] = id;
    q["cached"] = !computed;
    res.set_content(Dump(q), "application/json");
  }

  bool Authorised(const httplib::Request& req, httplib::Response& res) const {
    if (token_.empty()) {
      SendError(res, 403, "the admin API is off (start the server with --admin-token-file)");
      return false;
    }
    const std::string want = "Bearer " + token_;
    const std::string got = req.get_header_value("Authorization");
    // Compare in constant time over the expected length.
    unsigned diff = got.size() != want.size();
    for (std::size_t i = 0; i < want.size(); ++i) diff |= unsigned(want[i]) ^ unsigned(i < got.size() ? got[i] : 0);
    if (diff) {
      SendError(res, 401, "missing or wrong bearer token");
      return false;
    }
    return true;
  }

  static double Param(const httplib::Request& req, const char* name, double fallback) {
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

  void Recognize(const httplib::Request& req, httplib::Response& res) {
    // Bounded concurrency: refuse at once rather than queue (a connection
    // over the bound is served by the rejecting thread: cheap routes answer,
    // recognition does not).
    if (t_overloaded || inflight_.fetch_add(1) >= a_.max_inflight) {
      if (!t_overloaded) inflight_.fetch_sub(1);
      res.set_header("Retry-After", "1");
      return SendError(res, 503, "busy: " + std::to_string(a_.max_inflight) + " requests already being served");
    }
    struct Release {
      std::atomic<int>& n;
      ~Release() { n.fetch_sub(1); }
    } release{inflight_};
    Timer total;
    std::string body = req.body;
    if (req.is_multipart_form_data()) {
      if (!req.has_file("image")) return SendError(res, 400, "multipart request without an 'image' field");
      body = req.get_file_value("image").content;
    }
    if (body.empty()) return SendError(res, 400, "empty body: send a JPEG or PNG image");
    cv::Mat gray;
    ImageLimits lim;
    lim.max_pixels = a_.max_pixels;
    lim.max_file_bytes = std::int64_t(a_.max_body_mb) << 20;
    try {
      gray = DecodeImageGray("request body", std::vector<std::uint8_t>(body.begin(), body.end()), lim);
    } catch (const Error& e) {
      const bool too_big = std::string(e.what()).find("limit") != std::string::npos ||
                           std::string(e.what()).find("large") != std::string::npos;
      return SendError(res, too_big ? 413 : 400, e.what());
    }
    std::optional<CameraModel> cam;
    double width_m = 0;
    try {
      if (req.has_param("fx")) {
        CameraModel c;
        const double fx = Param(req, "fx", 0), fy = Param(req, "fy", fx);
        const double cx = Param(req, "cx", gray.cols / 2.0), cy = Param(req, "cy", gray.rows / 2.0);
        if (!(fx > 0 && fy > 0)) return SendError(res, 400, "fx and fy must be positive");
        c.K = cv::Matx33d(fx, 0, cx, 0, fy, cy, 0, 0, 1);
        c.dist = cv::Mat::zeros(1, 5, CV_64F);
        c.image_size = gray.size();
        cam = c;
        width_m = Param(req, "width_m", 0);
        if (width_m < 0) return SendError(res, 400, "width_m must be positive");
      }
    } catch (const Error& e) {
      return SendError(res, 400, e.what());
    }
    std::shared_lock<std::shared_mutex> lock(mutex_);
    const std::string prev = req.has_param("prev") ? req.get_param_value("prev") : "";
    RecognitionResult r;
    std::string mode = "full";
    if (!prev.empty() && rec_->Contains(prev)) {
      r = rec_->RecognizeOne(gray, prev);  // temporal focus (thesis §6.3.1)
      mode = "focus";
    }
    if (r.found.empty()) {
      r = rec_->Recognize(gray);
      mode = mode == "focus" ? "focus+full" : "full";
    }
    Json found = Json::array();
    for (const auto& f : r.found) {
      const TargetInfo& t = info_.at(f.id);
      Json x = RecognitionJson(f, t.title);
      x["artist"] = t.artist;
      x["year"] = t.year;
      x["url"] = t.url;
      if (cam) {
        double w = width_m;
        try {
          const Json meta = Json::parse(t.meta);
          if (meta.contains("width_m") && meta["width_m"].is_number()) w = meta["width_m"].get<double>();
        } catch (const std::exception&) {
        }
        if (w > 0) {
          const cv::Size s = size_.at(f.id);
          const Pose p = EstimatePose(f.homography, s.width, s.height, w, *cam);
          if (p.ok) x["pose"] = PoseSupport::Json(p);
        }
      }
      found.push_back(x);
    }
    res.set_content(Dump(Json{{"found", found},
                              {"mode", mode},
                              {"width", gray.cols},
                              {"height", gray.rows},
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
    auto field = [&](const char* k) { return req.has_file(k) ? req.get_file_value(k).content : std::string(); };
    TargetInfo info;
    info.id = field("id");
    info.title = field("title");
    info.artist = field("artist");
    info.year = field("year");
    info.url = field("url");
    info.meta = req.has_file("meta") ? field("meta") : "{}";
    if (info.id.find('/') != std::string::npos)
      return SendError(res, 400, "id must not contain '/' (ids are part of the exhibits' URLs)");
    const std::string img = field("image");
    Timer total;
    double train_ms = 0, quality_ms = 0;
    Json quality;
    std::unique_lock<std::mutex> admin(admin_mutex_);  // one writer
    try {
      ImageLimits lim;
      lim.max_pixels = a_.max_pixels;
      const cv::Mat gray = DecodeImageGray("image", std::vector<std::uint8_t>(img.begin(), img.end()), lim);
      TargetStore store = TargetStore::Open(a_.db, TargetStore::Mode::kReadWrite);
      if (store.Contains(info.id)) return SendError(res, 409, "exhibit '" + info.id + "' already exists");
      // The quality assessment (the longer job) runs beside the training.
      auto assessed = std::async(std::launch::async, [&gray] { return AssessTarget(gray, QualityOptions{}); });
      Timer train;
      TargetRecord r =
          MakeTargetRecord(info, std::vector<std::uint8_t>(img.begin(), img.end()), gray, DbTrainDefaults(), "image");
      train_ms = train.ElapsedMs();
      const QualityReport report = assessed.get();
      quality_ms = report.ms;
      quality = QualityJson(report, /*with_points=*/false);
      const std::string q = Dump(quality);
      r.encodings.push_back({kQualityEncoding, std::vector<std::uint8_t>(q.begin(), q.end())});
      store.Add(r);  // one transaction
    } catch (const Error& e) {
      return SendError(res, e.code() == ErrorCode::kIo ? 500 : 400, e.what());
    }
    Timer reload;
    ReloadAfterChange();
    const double reload_ms = reload.ElapsedMs();
    const TargetInfo added = TargetStore::Open(a_.db).Get(info.id, false).info;
    {
      std::lock_guard<std::mutex> lock(quality_mutex_);
      quality_[info.id] = {added.added_at, quality};
    }
    Json out = InfoJson(added);
    out["quality"] = quality;
    out["time_ms"] = {{"train", train_ms}, {"quality", quality_ms}, {"reload", reload_ms}, {"total", total.ElapsedMs()}};
    res.status = 201;
    res.set_content(Dump(out), "application/json");
  }

  void UpdateExhibit(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    Json j;
    try {
      j = Json::parse(req.body);
    } catch (const std::exception&) {
      return SendError(res, 400, "body is not JSON");
    }
    if (!j.is_object()) return SendError(res, 400, "body must be a JSON object");
    std::unique_lock<std::mutex> admin(admin_mutex_);
    try {
      TargetStore store = TargetStore::Open(a_.db, TargetStore::Mode::kReadWrite);
      const std::string id = req.matches[1];
      if (!store.Contains(id)) return SendError(res, 404, "no exhibit '" + id + "'");
      TargetInfo info = store.Get(id, false).info;
      auto str = [&](const char* k, std::string& dst) {
        if (!j.contains(k)) return;
        if (!j[k].is_string()) throw Error(ErrorCode::kInvalidArgument, std::string(k) + " must be a string");
        dst = j[k].get<std::string>();
      };
      str("title", info.title);
      str("artist", info.artist);
      str("year", info.year);
      str("url", info.url);
      if (j.contains("meta")) {
        if (!j["meta"].is_object()) throw Error(ErrorCode::kInvalidArgument, "meta must be a JSON object");
        info.meta = j["meta"].dump();
      }
      store.UpdateInfo(info);
    } catch (const Error& e) {
      return SendError(res, 400, e.what());
    }
    // Metadata only: the recogniser stays; recognitions see the new text at once.
    const TargetInfo updated = TargetStore::Open(a_.db).Get(req.matches[1], false).info;
    {
      std::unique_lock<std::shared_mutex> lock(mutex_);
      const auto it = info_.find(updated.id);
      if (it != info_.end()) it->second = updated;
    }
    res.set_content(Dump(InfoJson(updated)), "application/json");
  }

  void DeleteExhibit(const httplib::Request& req, httplib::Response& res) {
    if (!Authorised(req, res)) return;
    std::unique_lock<std::mutex> admin(admin_mutex_);
    TargetStore store = TargetStore::Open(a_.db, TargetStore::Mode::kReadWrite);
    if (!store.Remove(req.matches[1])) return SendError(res, 404, "no exhibit '" + std::string(req.matches[1]) + "'");
    {
      std::lock_guard<std::mutex> lock(quality_mutex_);
      quality_.erase(req.matches[1]);
    }
    ReloadAfterChange();
    res.status = 204;
  }

  void Log(const httplib::Request& req, const httplib::Response& res) {
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_request_start).count();
    const std::string route = RouteOf(req);
    Json line = {{"method", req.method}, {"path", req.path}, {"route", route}, {"status", res.status},
                 {"bytes_in", req.body.size()}, {"bytes_out", res.body.size()}, {"remote", req.remote_addr}};
    line["ms"] = ms;
    metrics_.Observe(route, res.status, ms / 1000.0);
    std::fprintf(stderr, "%s\n", Dump(line).c_str());
  }

  ServeArgs a_;
  RecognizerOptions options_;
  std::string token_;
  mutable std::shared_mutex mutex_;  // recognitions share it; a reload takes it alone
  std::shared_ptr<Recognizer> rec_;
  std::map<std::string, TargetInfo> info_;
  std::map<std::string, cv::Size> size_;
  std::mutex admin_mutex_;  // one writer; also serialises reloads
  std::unique_ptr<TargetStore> watch_store_;  // a connection kept open for its data_version
  std::uint64_t seen_version_ = 0;            // data_version of the last load (admin_mutex_)
  // Quality reports by id, with the added_at they belong to (an id deleted
  // and added again by another process gets a new report).
  struct CachedQuality {
    std::string added_at;
    Json report;
  };
  std::map<std::string, CachedQuality> quality_;
  std::mutex quality_mutex_;  // guards quality_
  std::mutex assess_mutex_;   // one on-demand assessment at a time
  std::atomic<int> inflight_{0};
  std::atomic<std::uint64_t> connections_cut_{0};  // by ConnectionDeadline
  Metrics metrics_;
};

}  // namespace

void RegisterServe(CLI::App& app, int* code) {
  auto a = std::make_shared<ServeArgs>();
  auto* c = app.add_subcommand("serve", "Museum guide server: recognition and exhibit information over HTTP");
  c->add_option("DB", a->db, "target database (mvkp db)")->required();
  c->add_option("--host", a->host, "address to listen on")->capture_default_str();
  c->add_option("--port", a->port, "port (0: any free port, printed at start)")->capture_default_str();
  c->add_option("--threads", a->threads, "worker threads")->capture_default_str()->check(CLI::Range(1, 256));
  c->add_option("--max-inflight", a->max_inflight,
                "connections served or waiting at once; more get 503 at once (0: 8 x threads)")
      ->capture_default_str();
  c->add_option("--admin-token-file", a->token_file, "file holding the admin bearer token (admin API off without it)");
  c->add_option("--max-body-mb", a->max_body_mb, "largest request body, MiB")->capture_default_str()->check(CLI::Range(1, 1024));
  c->add_option("--max-pixels", a->max_pixels, "largest image, pixels")->capture_default_str();
  c->add_option("--timeout", a->timeout_s, "read/write timeout per request, seconds")->capture_default_str()->check(CLI::Range(1, 3600));
  c->add_option("--max-connection-s", a->max_connection_s,
                "longest a client connection may last, seconds (cuts clients that trickle their request)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400.0));
  c->add_flag("--words", a->words, "recognise with the word search (thousands of exhibits)");
  c->add_option("--watch-db", a->watch_s,
                "seconds between checks for changes committed by others (replicas, mvkp db); 0: off")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  c->add_option("--probe-words", a->probe_words,
                "exact search: 0 compares with every centre; N only with those in the query's N nearest words")
      ->capture_default_str()
      ->check(CLI::Range(0, 65536));
  c->callback([a, code] {
    GuideServer server(*a);
    *code = server.Run();
  });
}

}  // namespace mvkp::cli
