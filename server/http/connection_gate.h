#pragma once
// The door of an HTTP listener (server/http/http_listen.h): it accepts the connections and hands
// each to the server that holds the routes, at most `per_client` at a time per remote address
// (IP); one more is answered 503 at once over plain HTTP, or closed over HTTPS (a TLS client
// would read a plain answer as garbage). A client that opens connections and sends nothing
// holds `per_client` workers at most, each until the read timeout.
//
// cpp-httplib (0.11) has no hook between accept() and serving a connection: its per-connection
// step, Server::process_and_close_socket, is a private virtual. The gate is a Server of its own
// that overrides that step and calls the routes' server's step, reached through an explicit
// template instantiation (which the language exempts from access checks; connection_gate.cc).
// Include only where httplib.h may come after Eigen (it pulls in <resolv.h>).
//
// Thread-safety: connections are served on the gate's worker threads; the counts are guarded.

#include <atomic>
#include <map>
#include <mutex>
#include <string>

#include "server/http/httplib_include.h"

namespace forestmap::server {

class ConnectionGate final : public httplib::Server {
 public:
  // `routes` serves what the gate lets through (its timeouts and routes apply); `https`: it is
  // an SSLServer (refusals are then closed without an answer).
  ConnectionGate(httplib::Server& routes, int per_client, bool https);

  // Lets `backlog` connections wait for accept() once bound (cpp-httplib listens with 5: a burst
  // of connections, one client's flood included, had the kernel drop the next clients' SYNs,
  // which they retry only after 1 s, 3 s, ...). False when the socket refused.
  bool WidenBacklog(int backlog);

  // Ends the keep-alive of the connections in service and refuses new ones; call before stop().
  void Close();

 private:
  bool process_and_close_socket(socket_t sock) override;
  bool Take(const std::string& address);
  void Give(const std::string& address);

  httplib::Server& routes_;
  const int per_client_;
  const bool https_;
  std::atomic<bool> closed_{false};
  std::mutex mutex_;
  std::map<std::string, int> serving_;  // connections in service per remote address; guarded
};

}  // namespace forestmap::server
