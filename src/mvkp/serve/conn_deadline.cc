#include "mvkp/serve/internal/conn_deadline.h"

#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <chrono>
#include <map>
#include <string>
#include <tuple>

namespace mvkp::serve {
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

constexpr std::chrono::seconds kBusyExtra(120);

std::string PeerName(const sockaddr_storage& peer) {
  char buf[INET6_ADDRSTRLEN] = {0};
  int port = 0;
  if (peer.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&peer);
    ::inet_ntop(AF_INET, &a->sin_addr, buf, sizeof buf);
    port = ntohs(a->sin_port);
  } else if (peer.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&peer);
    ::inet_ntop(AF_INET6, &a->sin6_addr, buf, sizeof buf);
    port = ntohs(a->sin6_port);
  }
  return std::string(buf) + "|" + std::to_string(port);
}

}  // namespace

ConnectionDeadline::ConnectionDeadline(int port, Ms limit, Ms read_limit, Ms period, Ms grace,
                                       std::atomic<std::uint64_t>* cut)
    : port_(port), limit_(limit), read_limit_(read_limit), period_(period), grace_(grace), cut_(cut),
      thread_([this] { Run(); }) {}

ConnectionDeadline::~ConnectionDeadline() {
  stop_ = true;
  thread_.join();
}

void ConnectionDeadline::Busy(const std::string& address, int port) {
  std::lock_guard<std::mutex> lock(mutex_);
  activity_[address + "|" + std::to_string(port)] = {true, std::chrono::steady_clock::now()};
}

void ConnectionDeadline::Idle(const std::string& address, int port) {
  std::lock_guard<std::mutex> lock(mutex_);
  activity_[address + "|" + std::to_string(port)] = {false, std::chrono::steady_clock::now()};
}

void ConnectionDeadline::Run() {
  using Clock = std::chrono::steady_clock;
  struct Seen {
    Clock::time_point first;
    Clock::time_point cut_at{};
    int stage = 0;  // 1: reading side shut, 2: both
  };
  std::map<std::string, Seen> seen;
  while (!stop_) {
    std::this_thread::sleep_for(period_);
    const auto now = Clock::now();
    std::map<std::string, Seen> next;
    std::map<std::string, Activity> live;  // activity of the peers still connected
    if (DIR* d = ::opendir("/proc/self/fd")) {
      std::lock_guard<std::mutex> lock(mutex_);
      while (dirent* e = ::readdir(d)) {
        char* end = nullptr;
        const long fd = std::strtol(e->d_name, &end, 10);
        if (end == e->d_name || *end != '\0' || fd < 0) continue;
        struct stat st {};
        if (::fstat(int(fd), &st) != 0 || !S_ISSOCK(st.st_mode)) continue;
        sockaddr_storage peer{};
        if (!PeerOn(int(fd), port_, peer)) continue;
        const std::string k = Key(int(fd), peer);
        const std::string name = PeerName(peer);
        auto it = seen.find(k);
        Seen s = it == seen.end() ? Seen{now} : it->second;
        // The read clock: since the connection was seen or last answered.
        // The read clock: since the connection was seen or last answered;
        // stopped while a handler works on its request.
        bool reading_too_long = now - s.first > read_limit_;
        bool busy = false;
        const auto a = activity_.find(name);
        if (a != activity_.end()) {
          live[name] = a->second;
          busy = a->second.busy;
          reading_too_long = !busy && now - std::max(a->second.since, s.first) > read_limit_;
        }
        // While the server works on a request (an admin add waits seconds
        // for the writer lock) the total limit gets kBusyExtra more: cutting
        // then would lose an answer to a change already made.
        const auto total = busy ? limit_ + kBusyExtra : limit_;
        if (s.stage == 0 && (now - s.first > total || reading_too_long)) {
          ::shutdown(int(fd), SHUT_RD);
          s.stage = 1;
          s.cut_at = now;
          if (cut_) ++*cut_;
        } else if (s.stage == 1 && now - s.cut_at > grace_) {
          ::shutdown(int(fd), SHUT_RDWR);
          s.stage = 2;
        }
        next.emplace(k, s);
      }
      ::closedir(d);
      // Peers no longer connected are forgotten (their ports get reused).
      for (auto it = activity_.begin(); it != activity_.end();) {
        if (!live.count(it->first) && now - it->second.since > 2 * period_ + std::chrono::seconds(1))
          it = activity_.erase(it);
        else
          ++it;
      }
    }
    seen = std::move(next);
  }
}

}  // namespace mvkp::serve
