// mvkp serve DB: the museum guide's server, a thin command over the service
// library (mvkp/serve/service.h holds the API, limits and behaviour).
#include <malloc.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <memory>
#include <thread>

#include "commands.h"
#include "mvkp/core/error.h"
#include "mvkp/core/atomic_file.h"
#include "mvkp/serve/service.h"

namespace mvkp::cli {
namespace {

struct ServeArgs {
  serve::ServiceOptions o;
  std::string token_file;
};

std::atomic<bool> g_stop{false};
extern "C" void OnSignal(int) { g_stop = true; }

int RunServe(ServeArgs& a) {
  // glibc gives each thread that allocates its own arena: with dozens of
  // connection workers, freed memory spread over them kept RSS growing
  // (+21 % in the 10 min soak). A few arenas serve the CPU-bound work as well.
  ::mallopt(M_ARENA_MAX, 4);
  if (!a.token_file.empty()) {
    const auto bytes = ReadFileBytes(a.token_file, 4096);
    std::string token(bytes.begin(), bytes.end());
    while (!token.empty() && (token.back() == '\n' || token.back() == '\r' || token.back() == ' ')) token.pop_back();
    Require(token.size() >= 16, ErrorCode::kInvalidArgument, a.token_file + ": admin token must be at least 16 characters");
    a.o.admin_token = token;
  }
  serve::Service service(a.o);
  service.Bind();
  std::signal(SIGTERM, OnSignal);
  std::signal(SIGINT, OnSignal);
  // The handler only raises a flag; this thread asks the service to stop.
  std::atomic<bool> done{false};
  std::thread watcher([&] {
    while (!g_stop && !done) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    service.Stop();
  });
  service.Run();
  done = true;
  watcher.join();
  return 0;
}

}  // namespace

void RegisterServe(CLI::App& app, int* code) {
  auto a = std::make_shared<ServeArgs>();
  serve::ServiceOptions& o = a->o;
  auto* c = app.add_subcommand("serve", "Museum guide server: recognition and exhibit information over HTTP");
  c->add_option("DB", o.db, "target database (mvkp db)")->required();
  c->add_option("--host", o.host, "address to listen on")->capture_default_str();
  c->add_option("--port", o.port, "port (0: any free port, printed at start)")->capture_default_str();
  c->add_flag("--reuse-port", o.reuse_port,
              "share the port with other processes (SO_REUSEPORT); without it a port in use is an error");
  c->add_option("--threads", o.threads, "CPU work at once: recognitions, thumbnails, quality, training")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  c->add_option("--io-threads", o.io_threads,
                "connection workers (slow clients hold one each, for at most --read-deadline-s)")
      ->capture_default_str()
      ->check(CLI::Range(2, 4096));
  c->add_option("--max-inflight", o.max_inflight, "recognitions admitted at once; more get 503 at once (0: 8 x threads)")
      ->capture_default_str();
  c->add_option("--admin-token-file", a->token_file, "file holding the admin bearer token (admin API off without it)");
  c->add_option("--max-body-mb", o.max_body_mb, "largest request body, MiB")->capture_default_str()->check(CLI::Range(1, 1024));
  c->add_option("--max-pixels", o.max_pixels, "largest image, pixels")->capture_default_str();
  c->add_option("--timeout", o.timeout_s, "read/write timeout per socket operation, seconds")
      ->capture_default_str()
      ->check(CLI::Range(1, 3600));
  c->add_option("--read-deadline-s", o.read_deadline_s,
                "time a client has to send each request, headers and body, seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 86400.0));
  c->add_option("--max-connection-s", o.max_connection_s, "longest a client connection may last, seconds")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400.0));
  c->add_option("--thumb-cache-mb", o.thumb_cache_mb, "thumbnails kept in memory, MiB")->capture_default_str();
  c->add_flag("--words", o.words, "recognise with the word search (thousands of exhibits)");
  c->add_option("--watch-db", o.watch_s,
                "seconds between checks for changes committed by others (replicas, mvkp db); 0: off")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  c->add_option("--site", o.site,
                "site.json: the museum's name, intro, colours and logo for the visitor page (GET /api/site)");
  c->add_option("--cert", o.cert, "PEM certificate (chain): serve HTTPS (phones give the camera to https pages only)");
  c->add_option("--key", o.key, "PEM private key of --cert");
  c->add_option("--probe-words", o.probe_words,
                "exact search: 0 compares with every centre; N only with those in the query's N nearest words")
      ->capture_default_str()
      ->check(CLI::Range(0, 65536));
  c->callback([a, code] { *code = RunServe(*a); });
}

}  // namespace mvkp::cli
