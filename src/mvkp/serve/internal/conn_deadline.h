// A total time limit per client connection of `mvkp serve`.
//
// cpp-httplib's read timeout applies to each read, so a client that trickles
// a byte every few seconds (headers or body; "slowloris") holds a worker
// thread for as long as it likes, and a few such clients hold them all. The
// server's handlers never see the socket, so this watchdog finds the
// connections itself: every `period` it lists the process's sockets
// (/proc/self/fd) that are connected to `port`, remembers when it first saw
// each (by descriptor and peer address), and when one is older than `limit`
// shuts down its reading side. The worker then reads end-of-file: a request
// body in progress is answered 400 and the connection closed. One still open
// `grace` later is shut down both ways (a client that does not read).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

namespace mvkp::cli {

class ConnectionDeadline {
 public:
  ConnectionDeadline(int port, std::chrono::milliseconds limit,
                     std::chrono::milliseconds period = std::chrono::milliseconds(250),
                     std::chrono::milliseconds grace = std::chrono::seconds(5),
                     std::atomic<std::uint64_t>* cut = nullptr);  // counts the connections cut
  ~ConnectionDeadline();  // stops the watchdog
  ConnectionDeadline(const ConnectionDeadline&) = delete;
  ConnectionDeadline& operator=(const ConnectionDeadline&) = delete;

 private:
  void Run();
  int port_;
  std::chrono::milliseconds limit_, period_, grace_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t>* cut_;
  std::thread thread_;
};

}  // namespace mvkp::cli
