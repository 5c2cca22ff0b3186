#include "server/http/connection_gate.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <nlohmann/json.hpp>

namespace forestmap::server {
namespace {

// How long a refused plain-HTTP connection is read after its answer, so that closing it with
// its request unread does not reset it before the client has read the 503.
constexpr auto kDrainLimit = std::chrono::milliseconds(100);

// Pointers to two non-public members of httplib::Server. Naming them in an explicit
// instantiation is exempt from access checks ([temp.spec.general]); the friend functions hand
// them out.
using ProcessSocket = bool (httplib::Server::*)(socket_t);
using ListenSocket = std::atomic<socket_t> httplib::Server::*;
ProcessSocket ProcessSocketMember();
ListenSocket ListenSocketMember();

template <ProcessSocket kProcess, ListenSocket kListen>
struct ServerMembers {
  friend ProcessSocket ProcessSocketMember() { return kProcess; }
  friend ListenSocket ListenSocketMember() { return kListen; }
};
template struct ServerMembers<&httplib::Server::process_and_close_socket,
                              &httplib::Server::svr_sock_>;

std::string PeerAddress(socket_t sock) {
  sockaddr_storage peer{};
  socklen_t length = sizeof(peer);
  if (getpeername(sock, reinterpret_cast<sockaddr*>(&peer), &length) != 0) return "";
  char text[INET6_ADDRSTRLEN] = {};
  const void* ip = nullptr;
  if (peer.ss_family == AF_INET) {
    ip = &reinterpret_cast<const sockaddr_in*>(&peer)->sin_addr;
  } else if (peer.ss_family == AF_INET6) {
    ip = &reinterpret_cast<const sockaddr_in6*>(&peer)->sin6_addr;
  }
  if (ip == nullptr || inet_ntop(peer.ss_family, ip, text, sizeof(text)) == nullptr) return "";
  return text;
}

// Answers 503 without reading the request, then closes the connection.
void Refuse(socket_t sock, int per_client) {
  const std::string body =
      nlohmann::json{{"error", "too many connections from this address (" +
                                   std::to_string(per_client) + " at a time): close one and retry"}}
          .dump();
  const std::string answer =
      "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
      "Connection: close\r\nRetry-After: 1\r\nContent-Length: " +
      std::to_string(body.size()) + "\r\n\r\n" + body;
  if (send(sock, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT) > 0) {
    shutdown(sock, SHUT_WR);
    const auto until = std::chrono::steady_clock::now() + kDrainLimit;
    char buffer[4096];
    for (auto now = std::chrono::steady_clock::now(); now < until;
         now = std::chrono::steady_clock::now()) {
      pollfd wait{sock, POLLIN, 0};
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - now);
      if (poll(&wait, 1, static_cast<int>(left.count()) + 1) <= 0) break;
      if (recv(sock, buffer, sizeof(buffer), MSG_DONTWAIT) <= 0) break;
    }
  }
  close(sock);
}

}  // namespace

ConnectionGate::ConnectionGate(httplib::Server& routes, int per_client, bool https)
    : routes_(routes), per_client_(per_client), https_(https) {}

bool ConnectionGate::WidenBacklog(int backlog) {
  // listen() on a listening socket sets its backlog anew.
  return ::listen(svr_sock_.load(), backlog) == 0;
}

void ConnectionGate::Close() {
  closed_ = true;
  // The routes' server keeps a connection alive only while its listening socket is valid.
  (routes_.*ListenSocketMember()) = INVALID_SOCKET;
}

bool ConnectionGate::process_and_close_socket(socket_t sock) {
  const std::string address = PeerAddress(sock);
  if (closed_ || !Take(address)) {
    if (https_ || closed_) {
      close(sock);
    } else {
      Refuse(sock, per_client_);
    }
    return false;
  }
  struct Release {
    ConnectionGate& gate;
    const std::string& address;
    ~Release() { gate.Give(address); }
  } release{*this, address};
  // The routes' server never listens itself: its socket only marks it as serving.
  (routes_.*ListenSocketMember()) = svr_sock_.load();
  return (routes_.*ProcessSocketMember())(sock);  // closes sock
}

bool ConnectionGate::Take(const std::string& address) {
  const std::lock_guard lock(mutex_);
  int& serving = serving_[address];
  if (serving >= per_client_) return false;
  ++serving;
  return true;
}

void ConnectionGate::Give(const std::string& address) {
  const std::lock_guard lock(mutex_);
  if (--serving_[address] <= 0) serving_.erase(address);
}

}  // namespace forestmap::server
