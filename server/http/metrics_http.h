#pragma once
// The HTTP endpoint of forestmapd's metrics (--metrics ADDR), for monitoring and orchestrators:
//   GET /metrics  the Prometheus text exposition
//   GET /healthz  200 "ok" while the process serves (liveness)
//   GET /readyz   200 "ready", or 503 with the reason (readiness: server/app/readiness.h)
//   GET /         the list of these
// anything else 404. On its own port (cpp-httplib): plain HTTP, so bound to loopback or a
// monitoring network, or HTTPS with an HttpsSetup (forestmapd's --metrics-tls: the gRPC port's
// certificate and client verification).
// Thread-safety: the constructor starts a thread that serves until the destructor stops it.

#include <functional>
#include <string>
#include <utility>

#include "server/http/http_listen.h"

namespace forestmap::server {

class MetricsHttpServer {
 public:
  using Render = std::function<std::string()>;
  // Whether the server is ready, and why not ("" when ready).
  using Ready = std::function<std::pair<bool, std::string>()>;

  // Binds `address` ("host:port"; port 0 picks a free one) and serves `render()` on /metrics and
  // `ready()` on /readyz (HTTPS with `https`). Throws std::runtime_error when the address cannot
  // be bound or is malformed. Destroying it stops serving and joins the thread.
  MetricsHttpServer(const std::string& address, Render render, Ready ready,
                    const HttpsSetup& https = {});

  int port() const { return listener_.port(); }
  std::string url() const { return listener_.url(); }  // http(s)://host:port

 private:
  HttpListener listener_;
};

// The routes above, added to `http` (also driven by tests/fuzz/fuzz_http_routes.cc).
void AddMetricsRoutes(httplib::Server& http, MetricsHttpServer::Render render,
                      MetricsHttpServer::Ready ready);

}  // namespace forestmap::server
