// The museum guide's HTTP service (issue 7, thesis §6.3.2): it recognises
// frames sent by phones and holds the exhibits' information. `mvkp serve` is
// a thin command over it; an application can embed it.
//
//   POST /api/recognize[?prev=ID,ID,...&fx=&fy=&cx=&cy=&width_m=]  JPEG/PNG
//        body or multipart field "image" -> every exhibit found (id, title,
//        artist, year, url, outline, homography, inliers, score[, pose]; most
//        inliers first), "mode" and timings. Each frame gets the full search
//        (new exhibits are found whatever prev says); prev lists the exhibits
//        the client saw in its last frame (at most 20 ids, or repeated prev
//        parameters; ids no longer stored are ignored): the full search
//        verifies as many more candidates as ids are known, and those it
//        missed get a focused check each (mode "full+focus"). An empty item,
//        a bad id or more than 20 ids: 400.
//   GET  /api/exhibits, /api/exhibits/{id}, /api/exhibits/{id}/image
//        [?thumb=N: a JPEG at most N px on its longest side, 16..1024]
//        (request JPEGs are decoded reduced, DCT scaling, and answered in
//        the photo's pixels)
//   POST /api/exhibits (multipart: image, id, title, artist, year, url, meta
//        [, allow_duplicate=1]) -> 201 with the exhibit and its target
//        quality ("quality"); 409 with "duplicates" when the photo shows an
//        exhibit already there (add and replace)
//   PUT  /api/exhibits/{id} (JSON object with any of title, artist, year,
//        url, meta), DELETE /api/exhibits/{id},
//   PUT  /api/exhibits/{id}/image (the new photo as the body or multipart
//        field "image"): retrains it; a refused image keeps the old model,
//   GET  /api/exhibits/{id}/quality (the report of `mvkp quality`),
//   GET  /api/admin/check (204: the token is right):
//        admin, "Authorization: Bearer TOKEN"; without a token the admin API
//        is off (403)
//   GET  /healthz (status "ok", or "degraded" with what is wrong: exhibits
//        skipped as unreadable, failing reloads), /metrics (Prometheus text)
//   GET  /api/site (the museum's name, intro, colours and logo URL, from
//        --site or defaults: site.h), /api/site/logo
//   GET  /, /admin: the web client and the admin page (web/, linked in);
//        /sw.js, the client's service worker (offline cards)
//
// HTTPS: with `cert` and `key` the same routes, limits and deadlines are
// served over TLS only (phones give the camera to https pages only).
//
// Hostile and broken input: request bodies and stored metadata are parsed
// with depth and size limits (mvkp/db/json_limits.h); ids, links and fields
// follow the store's rules (ValidateTargetInfo), checked before any training;
// a method a path does not take gets 405 with Allow; a POST or PUT without a
// length gets 411 at once; wrong admin tokens from one address are slowed
// (429 with Retry-After) after a few; a damaged exhibit row is skipped and
// reported instead of stopping the service; 5xx answers carry no internal
// detail (it goes to the log).
//
// Threads and limits: `io_threads` workers read requests and answer cheap
// routes; CPU work (recognition, thumbnails, quality, training) runs at most
// `threads` at a time, and at most `max_inflight` recognitions are admitted
// (running or waiting): more get 503 at once. A connection must deliver each
// request within `read_deadline_s` (not counting the server's own work) and
// may last at most `max_connection_s` in all, so slow clients cost a worker
// for seconds, not forever; a handful of them leave the others to serve.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "mvkp/recognize/recognizer.h"

namespace mvkp::serve {

struct ServiceOptions {
  std::string db;                     // target database (mvkp db), must exist
  std::string host = "127.0.0.1";
  int port = 8080;                    // 0: any free port (see Service::port)
  bool reuse_port = false;            // SO_REUSEPORT: share the port with other processes, on purpose only
  int backlog = 128;                  // listen queue
  int threads = 2;                    // CPU work at once (recognition, thumbnails, quality, training)
  int io_threads = 64;                // connection workers (keep-alive clients hold one each)
  int max_inflight = 0;               // recognitions admitted at once (0: 8 x threads); more get 503
  std::size_t max_body_mb = 48;       // largest request body (a 48 MP phone JPEG is 15-30 MB)
  // Largest request image (a 48 MP phone photo fits); request JPEGs are
  // decoded reduced to ~2000 px, larger stored images too.
  std::int64_t max_pixels = 64'000'000;
  int timeout_s = 10;                 // per read/write
  double read_deadline_s = 10;        // to deliver one request, headers and body (at most max_connection_s)
  double max_connection_s = 30;       // total per connection
  double watch_s = 2;                 // database change polling period (0: off)
  std::size_t thumb_cache_mb = 32;    // thumbnails kept in memory
  std::string admin_token;            // empty: admin API off; else at least 16 characters
  int token_failures_before_delay = 5;  // wrong tokens from one address before 429s begin
  bool words = false;                 // word search (thousands of exhibits)
  int probe_words = RecognizerOptions{}.probe_words;
  // One JSON line per event and request (default: stderr).
  std::function<void(const std::string&)> log;
  std::string site;                   // site file (name, colours, logo, intro: site.h); "" for the defaults
  std::string cert, key;              // PEM certificate (chain) and private key: HTTPS; both or neither

  // Throws Error(kInvalidArgument) naming the option that is out of range.
  void Check() const;
};

class Service {
 public:
  // Opens the database and loads its exhibits (a damaged one is skipped and
  // reported), the site file and the certificate. Throws Error for bad
  // options, a database that cannot be read, a bad site file (naming the key)
  // or a certificate/key that cannot be used (naming the file and why).
  explicit Service(ServiceOptions options);
  ~Service();  // stops Run (in any thread) and waits for it to return
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  // Binds host:port and returns the port. Throws Error(kIo) naming the
  // address when it cannot (in use by another process, not allowed).
  int Bind();
  // Serves until Stop() (Bind first, or Run binds). Finishes requests in
  // flight before returning.
  void Run();
  // Thread-safe; Run returns soon after.
  void Stop();
  int port() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mvkp::serve
