#pragma once
// The HTTP endpoint of forestmapd's metrics (--metrics ADDR): GET /metrics answers the
// Prometheus text exposition; anything else 404. Plain HTTP on its own port (cpp-httplib), so
// bind it to loopback or a monitoring network.
// Thread-safety: the constructor starts a thread that serves until the destructor stops it.

#include <functional>
#include <string>

#include "server/http/http_listen.h"

namespace forestmap::server {

class MetricsHttpServer {
 public:
  using Render = std::function<std::string()>;

  // Binds `address` ("host:port"; port 0 picks a free one) and serves `render()` on /metrics.
  // Throws std::runtime_error when the address cannot be bound or is malformed.
  // Destroying it stops serving and joins the thread.
  MetricsHttpServer(const std::string& address, Render render);

  int port() const { return listener_.port(); }

 private:
  HttpListener listener_;
};

}  // namespace forestmap::server
