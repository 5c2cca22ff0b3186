#include "server/http/http_listen.h"

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "server/http/connection_gate.h"
#include "server/http/handshake_deadline.h"
#include "server/http/httplib_include.h"

namespace forestmap::server {
namespace {

constexpr int kMaxPort = 65535;
constexpr auto kStopPoll = std::chrono::milliseconds(5);  // while waiting for the listen loop
// A connection that sends nothing (half-open, a slow client) holds one of cpp-httplib's workers
// until its read timeout; with its defaults (8 workers, 5 s) 50 such connections stalled the
// page and /metrics for 30 s. Many workers and a short first-byte timeout keep them answering.
constexpr int kHttpWorkers = 64;
constexpr int kReadTimeoutS = 2;
// Connections waiting for accept() (the kernel caps it at net.core.somaxconn).
constexpr int kAcceptBacklog = 1024;
// A whole TLS handshake, however its client drips its bytes.
constexpr auto kHandshakeLimit = std::chrono::seconds(5);

struct HostPort {
  std::string host;  // without the brackets of an IPv6 literal
  int port = -1;
};

HostPort Parse(const std::string& flag, const std::string& address) {
  const size_t colon = address.rfind(':');
  const std::string digits = colon == std::string::npos ? "" : address.substr(colon + 1);
  HostPort parsed;
  if (colon != std::string::npos && colon > 0) parsed.host = address.substr(0, colon);
  if (parsed.host.size() > 2 && parsed.host.front() == '[' && parsed.host.back() == ']') {
    parsed.host = parsed.host.substr(1, parsed.host.size() - 2);  // [::1]:9090
  }
  const bool numeric = !digits.empty() && digits.size() <= 5 &&
                       std::all_of(digits.begin(), digits.end(),
                                   [](unsigned char c) { return std::isdigit(c) != 0; });
  if (numeric) parsed.port = std::stoi(digits);
  if (parsed.host.empty() || parsed.port < 0 || parsed.port > kMaxPort) {
    throw std::runtime_error(flag + " " + address + ": give host:port (port 0 to " +
                             std::to_string(kMaxPort) + ", 0: any free one)");
  }
  return parsed;
}

// Why `host`:`port` cannot be bound: tries it with a socket of our own (httplib does not say).
std::string BindFailure(const HostPort& where) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(where.port);
  const int resolved = getaddrinfo(where.host.c_str(), service.c_str(), &hints, &found);
  if (resolved != 0) return std::string("cannot resolve the host: ") + gai_strerror(resolved);
  std::string reason = "cannot bind";
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    const int sock = socket(a->ai_family, a->ai_socktype, a->ai_protocol);
    if (sock < 0) continue;
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    const int bound = bind(sock, a->ai_addr, a->ai_addrlen);
    const int error = errno;
    close(sock);
    if (bound == 0) continue;
    reason = std::strerror(error);
    if (!reason.empty()) reason[0] = static_cast<char>(std::tolower(reason[0]));
    break;
  }
  freeaddrinfo(found);
  return reason;
}

}  // namespace

void SetConnectionTimeouts(httplib::Server& http) {
  http.set_read_timeout(kReadTimeoutS, 0);
  http.set_keep_alive_timeout(kReadTimeoutS);
}

int BindHttpListener(httplib::Server& http, const std::string& flag, const std::string& address) {
  const HostPort where = Parse(flag, address);
  http.new_task_queue = [] { return new httplib::ThreadPool(kHttpWorkers); };
  SetConnectionTimeouts(http);
  http.set_socket_options([](int sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  const int port = where.port == 0 ? http.bind_to_any_port(where.host)
                                   : (http.bind_to_port(where.host, where.port) ? where.port : -1);
  if (port <= 0) throw std::runtime_error(flag + " " + address + ": " + BindFailure(where));
  return port;
}

std::string BoundHttpAddress(const std::string& address, int port) {
  return address.substr(0, address.rfind(':')) + ":" + std::to_string(port);
}

HttpListener::HttpListener(const std::string& flag, const std::string& address,
                           const HttpsSetup& https, const Routes& routes) {
  if (https) {
    deadline_ = std::make_unique<HandshakeDeadline>(kHandshakeLimit);
    http_ = std::make_unique<httplib::SSLServer>(
        [&https, this](SSL_CTX& ctx) { return https(ctx) && deadline_->Install(ctx); });
    if (!http_->is_valid()) throw std::runtime_error(flag + " " + address + ": cannot set up TLS");
  } else {
    http_ = std::make_unique<httplib::Server>();
  }
  routes(*http_);
  SetConnectionTimeouts(*http_);  // it serves the connections the gate accepts
  gate_ = std::make_unique<ConnectionGate>(*http_, kConnectionsPerClient, static_cast<bool>(https));
  port_ = BindHttpListener(*gate_, flag, address);
  if (!gate_->WidenBacklog(kAcceptBacklog)) {
    throw std::runtime_error(flag + " " + address + ": cannot set the listen backlog");
  }
  address_ = BoundHttpAddress(address, port_);
  thread_ = std::thread([this] {
    gate_->listen_after_bind();
    stopped_ = true;
  });
}

HttpListener::~HttpListener() {
  gate_->Close();
  // stop() is a no-op until the listen loop runs: repeat it until the loop has ended.
  while (!stopped_) {
    gate_->stop();
    std::this_thread::sleep_for(kStopPoll);
  }
  thread_.join();
}

}  // namespace forestmap::server
