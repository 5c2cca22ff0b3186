#include "server/http/metrics_http.h"

#include <httplib.h>

#include <memory>
#include <utility>

namespace forestmap::server {
namespace {

constexpr const char* kText = "text/plain; charset=utf-8";

std::unique_ptr<httplib::Server> MetricsRoutes(MetricsHttpServer::Render render,
                                               MetricsHttpServer::Ready ready) {
  auto http = std::make_unique<httplib::Server>();
  http->Get("/metrics",
            [render = std::move(render)](const httplib::Request&, httplib::Response& response) {
              response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
            });
  http->Get("/healthz", [](const httplib::Request&, httplib::Response& response) {
    response.set_content("ok\n", kText);
  });
  http->Get("/readyz",
            [ready = std::move(ready)](const httplib::Request&, httplib::Response& response) {
              const auto [is_ready, reason] = ready();
              response.status = is_ready ? 200 : 503;
              response.set_content(is_ready ? "ready\n" : "not ready: " + reason + "\n", kText);
            });
  http->Get("/", [](const httplib::Request&, httplib::Response& response) {
    response.set_content(
        "forestmapd\n/metrics  Prometheus metrics\n/healthz  liveness\n/readyz   readiness\n",
        kText);
  });
  return http;
}

}  // namespace

MetricsHttpServer::MetricsHttpServer(const std::string& address, Render render, Ready ready)
    : listener_(MetricsRoutes(std::move(render), std::move(ready)), "--metrics", address) {}

}  // namespace forestmap::server
