#pragma once
// A bound on the whole TLS handshake of an HTTPS listener (server/http/http_listen.h).
// cpp-httplib bounds each wait for the client's bytes by the read timeout, not the handshake: a
// client sending one byte of its hello every second would hold a worker for minutes. Each
// handshake is watched from its start; one still running after `limit` has its socket shut down,
// so it fails and the worker takes the next connection.
// Thread-safety: handshakes start and end on any thread; one thread of its own watches them.

#include <openssl/types.h>

#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <thread>

namespace forestmap::server {

class HandshakeDeadline {
 public:
  explicit HandshakeDeadline(std::chrono::milliseconds limit);
  ~HandshakeDeadline();  // stops watching; every context installed on must be gone or idle
  HandshakeDeadline(const HandshakeDeadline&) = delete;
  HandshakeDeadline& operator=(const HandshakeDeadline&) = delete;

  // Watches every handshake of connections made with `ctx` (its info callback and data).
  bool Install(SSL_CTX& ctx);

 private:
  using Clock = std::chrono::steady_clock;
  struct Handshake {
    int fd = -1;
    Clock::time_point deadline;
  };
  static void OnInfo(const SSL* ssl, int where, int ret);
  void Watch(const SSL* ssl, int fd);
  void Forget(const SSL* ssl);
  void Run();

  const std::chrono::milliseconds limit_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool stop_ = false;                           // guarded
  std::map<const SSL*, Handshake> handshakes_;  // running ones; guarded
  std::thread thread_;
  friend struct HandshakeDeadlineAccess;
};

}  // namespace forestmap::server
