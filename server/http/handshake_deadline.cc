#include "server/http/handshake_deadline.h"

#include <openssl/crypto.h>
#include <openssl/ssl.h>
#include <sys/socket.h>

#include <algorithm>

namespace forestmap::server {

// OpenSSL's callbacks are plain functions: they reach the deadline through the data of the
// context (set by Install) and of the connection (set as its handshake starts, so that freeing
// the connection forgets it even when the handshake failed).
struct HandshakeDeadlineAccess {
  static int ContextIndex() {
    static const int index = SSL_CTX_get_ex_new_index(0, nullptr, nullptr, nullptr, nullptr);
    return index;
  }
  static int ConnectionIndex() {
    static const int index = SSL_get_ex_new_index(0, nullptr, nullptr, nullptr, &Freed);
    return index;
  }
  // Called by SSL_free, which cpp-httplib calls before it closes the socket: the socket is
  // never shut down after it could belong to another connection.
  static void Freed(void* parent, void* deadline, CRYPTO_EX_DATA*, int, long, void*) {
    if (deadline != nullptr)
      static_cast<HandshakeDeadline*>(deadline)->Forget(static_cast<SSL*>(parent));
  }
  static void Watch(HandshakeDeadline& deadline, const SSL* ssl, int fd) {
    deadline.Watch(ssl, fd);
  }
  static void Forget(HandshakeDeadline& deadline, const SSL* ssl) { deadline.Forget(ssl); }
};

HandshakeDeadline::HandshakeDeadline(std::chrono::milliseconds limit)
    : limit_(limit), thread_([this] { Run(); }) {}

HandshakeDeadline::~HandshakeDeadline() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

bool HandshakeDeadline::Install(SSL_CTX& ctx) {
  using Access = HandshakeDeadlineAccess;
  if (Access::ContextIndex() < 0 || Access::ConnectionIndex() < 0) return false;
  if (SSL_CTX_set_ex_data(&ctx, Access::ContextIndex(), this) != 1) return false;
  SSL_CTX_set_info_callback(&ctx, &HandshakeDeadline::OnInfo);
  return true;
}

void HandshakeDeadline::OnInfo(const SSL* ssl, int where, int /*ret*/) {
  using Access = HandshakeDeadlineAccess;
  if ((where & (SSL_CB_HANDSHAKE_START | SSL_CB_HANDSHAKE_DONE)) == 0) return;
  auto* deadline = static_cast<HandshakeDeadline*>(
      SSL_CTX_get_ex_data(SSL_get_SSL_CTX(ssl), Access::ContextIndex()));
  if (deadline == nullptr) return;
  if ((where & SSL_CB_HANDSHAKE_START) != 0) {
    // The callback gets a const connection; its data is the deadline's own bookkeeping.
    SSL_set_ex_data(const_cast<SSL*>(ssl), Access::ConnectionIndex(), deadline);
    Access::Watch(*deadline, ssl, SSL_get_fd(ssl));
  } else {
    Access::Forget(*deadline, ssl);
  }
}

void HandshakeDeadline::Watch(const SSL* ssl, int fd) {
  if (fd < 0) return;
  {
    const std::lock_guard lock(mutex_);
    handshakes_[ssl] = {fd, Clock::now() + limit_};
  }
  changed_.notify_all();
}

void HandshakeDeadline::Forget(const SSL* ssl) {
  const std::lock_guard lock(mutex_);
  handshakes_.erase(ssl);
}

void HandshakeDeadline::Run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    if (handshakes_.empty()) {
      changed_.wait(lock);
    } else {
      // A copy: waiting releases the lock, and Forget may erase the entry meanwhile.
      const Clock::time_point next =
          std::min_element(
              handshakes_.begin(), handshakes_.end(),
              [](const auto& a, const auto& b) { return a.second.deadline < b.second.deadline; })
              ->second.deadline;
      changed_.wait_until(lock, next);
    }
    const Clock::time_point now = Clock::now();
    for (auto it = handshakes_.begin(); it != handshakes_.end();) {
      if (it->second.deadline > now) {
        ++it;
        continue;
      }
      // Under the lock: the connection is not freed (Forget waits), so the socket is its own.
      shutdown(it->second.fd, SHUT_RDWR);
      it = handshakes_.erase(it);
    }
  }
}

}  // namespace forestmap::server
