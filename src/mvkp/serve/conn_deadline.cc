#include "conn_deadline.h"

#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <tuple>

namespace mvkp::cli {
namespace {

// The peer of `fd` if it is a TCP socket connected on local port `port`.
bool PeerOn(int fd, int port, sockaddr_storage& peer) {
  sockaddr_storage local{};
  socklen_t n = sizeof(local);
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &n) != 0) return false;
  int lport = -1;
  if (local.ss_family == AF_INET) lport = ntohs(reinterpret_cast<sockaddr_in*>(&local)->sin_port);
  else if (local.ss_family == AF_INET6) lport = ntohs(reinterpret_cast<sockaddr_in6*>(&local)->sin6_port);
  if (lport != port) return false;
  n = sizeof(peer);
  std::memset(&peer, 0, sizeof(peer));
  return ::getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &n) == 0;  // the listener has none
}

std::string Key(int fd, const sockaddr_storage& peer) {
  std::string k(reinterpret_cast<const char*>(&fd), sizeof(fd));
  k.append(reinterpret_cast<const char*>(&peer), sizeof(peer));
  return k;
}

}  // namespace

ConnectionDeadline::ConnectionDeadline(int port, std::chrono::milliseconds limit, std::chrono::milliseconds period,
                                       std::chrono::milliseconds grace, std::atomic<std::uint64_t>* cut)
    : port_(port), limit_(limit), period_(period), grace_(grace), cut_(cut), thread_([this] { Run(); }) {}

ConnectionDeadline::~ConnectionDeadline() {
  stop_ = true;
  thread_.join();
}

void ConnectionDeadline::Run() {
  using Clock = std::chrono::steady_clock;
  struct Seen {
    Clock::time_point first;
    int stage = 0;  // 1: reading side shut, 2: both
  };
  std::map<std::string, Seen> seen;
  while (!stop_) {
    std::this_thread::sleep_for(period_);
    const auto now = Clock::now();
    std::map<std::string, Seen> next;
    if (DIR* d = ::opendir("/proc/self/fd")) {
      while (dirent* e = ::readdir(d)) {
        char* end = nullptr;
        const long fd = std::strtol(e->d_name, &end, 10);
        if (end == e->d_name || *end != '\0' || fd < 0) continue;
        struct stat st {};
        if (::fstat(int(fd), &st) != 0 || !S_ISSOCK(st.st_mode)) continue;
        sockaddr_storage peer{};
        if (!PeerOn(int(fd), port_, peer)) continue;
        const std::string k = Key(int(fd), peer);
        auto it = seen.find(k);
        Seen s = it == seen.end() ? Seen{now, 0} : it->second;
        const auto age = now - s.first;
        if (s.stage == 0 && age > limit_) {
          ::shutdown(int(fd), SHUT_RD);
          s.stage = 1;
          if (cut_) ++*cut_;
        } else if (s.stage == 1 && age > limit_ + grace_) {
          ::shutdown(int(fd), SHUT_RDWR);
          s.stage = 2;
        }
        next.emplace(k, s);
      }
      ::closedir(d);
    }
    seen = std::move(next);
  }
}

}  // namespace mvkp::cli
