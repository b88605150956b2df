// The guide service's request handling on raw bytes: HTTP parsing, routing,
// methods, multipart and JSON bodies, ids, limits, the admin API. One service
// (mvkp/serve/service.h) runs in this process on a loopback port over a
// database of one exhibit; each input is sent as it is on a new connection,
// the writing side closed, and the answer read. Besides crashes and sanitizer
// reports, an answer 5xx other than 503 is a failure: the service must say
// what is wrong with a request (4xx), not fail on it.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mvkp/db/target_store.h"
#include "mvkp/recognize/target_db.h"
#include "mvkp/serve/service.h"

namespace {

// The admin token the seed corpus uses (fuzz/corpus/serve_request/).
constexpr const char* kToken = "fuzz-admin-token-0123456789";

int g_port = 0;

// A textured 320x240 target, so training succeeds without sample files.
cv::Mat Texture() {
  cv::Mat noise(60, 80, CV_8U);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat img;
  cv::resize(noise, img, cv::Size(320, 240), 0, 0, cv::INTER_CUBIC);
  return img;
}

// A connection to the server. connect() can fail transiently: libFuzzer's
// timer signal interrupts it (EINTR) while the accept queue is full, or the
// queue refuses for a moment; retried for up to ~5 s, then a server that
// still takes no connection is a finding (abort, with the reason).
int Connect() {
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(std::uint16_t(g_port));
  sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  int err = 0;
  for (int attempt = 0; attempt < 100; ++attempt) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0) std::abort();
    if (::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) == 0) return fd;
    err = errno;
    ::close(fd);
    if (err != EINTR) ::usleep(50000);
  }
  std::fprintf(stderr, "serve_request_fuzz: no connection to the server: %s\n", std::strerror(err));
  std::abort();
}

std::string Send(const std::uint8_t* data, std::size_t size) {
  const int fd = Connect();
  timeval tv{60, 0};  // the first quality report takes seconds under ASan
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  for (std::size_t sent = 0; sent < size;) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may close early (a bad request line)
    sent += std::size_t(n);
  }
  ::shutdown(fd, SHUT_WR);
  std::string answer;
  char buf[4096];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) answer.append(buf, std::size_t(n));
  ::close(fd);
  return answer;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("mvkp_fuzz_serve_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string db = (dir / "museum.db").string();
  {
    mvkp::TargetStore store = mvkp::TargetStore::Create(db);
    const cv::Mat img = Texture();
    std::vector<std::uint8_t> png;
    cv::imencode(".png", img, png);
    mvkp::TargetInfo info;
    info.id = "starry";
    info.title = "Texture";
    store.Add(mvkp::MakeTargetRecord(info, png, img, mvkp::DbTrainDefaults(), "texture"));
  }
  mvkp::serve::ServiceOptions o;
  o.db = db;
  o.port = 0;
  o.admin_token = kToken;
  o.token_failures_before_delay = 1 << 30;  // inputs guess tokens all the time
  o.watch_s = 0;
  o.timeout_s = 1;
  o.read_deadline_s = 2;
  o.max_connection_s = 5;
  o.log = [](const std::string& line) {
    if (line.find("\"internal error\"") != std::string::npos) std::fprintf(stderr, "%s\n", line.c_str());
  };
  static mvkp::serve::Service service(o);
  g_port = service.Bind();
  std::thread([] { service.Run(); }).detach();
  // The quality report costs seconds once, then it is cached: take that
  // cost here, not in an input's time limit.
  const std::string warm = std::string("GET /api/exhibits/starry/quality HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer ") +
                           kToken + "\r\n\r\n";
  Send(reinterpret_cast<const std::uint8_t*>(warm.data()), warm.size());
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string answer = Send(data, size);
  // "HTTP/1.1 NNN ..." when the server answered at all.
  if (answer.size() >= 12 && answer.compare(0, 5, "HTTP/") == 0) {
    const int status = std::atoi(answer.c_str() + 9);
    if (status >= 500 && status != 503) {
      std::fprintf(stderr, "answer %d:\n%s\n", status, answer.substr(0, 400).c_str());
      std::abort();
    }
  }
  return 0;
}
