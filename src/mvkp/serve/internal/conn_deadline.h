// Time limits per client connection of the guide service.
//
// cpp-httplib's read timeout applies to each read, so a client that trickles
// a byte every few seconds (headers or body; "slowloris") holds a worker
// thread for as long as it likes, and a few such clients hold them all. The
// handlers never see the socket, so this watchdog finds the connections
// itself: every `period` it lists the process's sockets (/proc/self/fd) that
// are connected to `port` and remembers when it first saw each (by descriptor
// and peer address). Two limits:
//  - `read_limit`: a connection must deliver each request (headers and body)
//    within this time of being accepted or of its previous answer. Handlers
//    mark the time they run (Busy) and answer (Idle), by peer address, so
//    slow work (training) is not counted, only the client's own slowness.
//  - `limit`: the total life of a connection (2 minutes more while a
//    handler works on its request, so an answer to a change already made is
//    not lost).
// A connection over a limit has its reading side shut down: the worker reads
// end-of-file, a request in progress is answered 400 and the connection
// closed. One still open `grace` later is shut down both ways (a client that
// does not read).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace mvkp::serve {

class ConnectionDeadline {
 public:
  using Ms = std::chrono::milliseconds;
  ConnectionDeadline(int port, Ms limit, Ms read_limit, Ms period = Ms(250), Ms grace = std::chrono::seconds(5),
                     std::atomic<std::uint64_t>* cut = nullptr);  // counts the connections cut
  ~ConnectionDeadline();  // stops the watchdog
  ConnectionDeadline(const ConnectionDeadline&) = delete;
  ConnectionDeadline& operator=(const ConnectionDeadline&) = delete;

  // A request from this peer ("address", port) has been read and is being
  // handled: its read clock stops.
  void Busy(const std::string& address, int port);
  // Its answer is written: the read clock restarts for the next request.
  void Idle(const std::string& address, int port);

 private:
  struct Activity {
    bool busy = false;
    std::chrono::steady_clock::time_point since;
  };
  void Run();
  int port_;
  Ms limit_, read_limit_, period_, grace_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t>* cut_;
  std::mutex mutex_;
  std::map<std::string, Activity> activity_;  // by "address|port"
  std::thread thread_;
};

}  // namespace mvkp::serve
