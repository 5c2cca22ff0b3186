#include "server/http/metrics_http.h"

#include <utility>

#include "server/http/httplib_include.h"

namespace forestmap::server {
namespace {

constexpr const char* kText = "text/plain; charset=utf-8";

}  // namespace

void AddMetricsRoutes(httplib::Server& http, MetricsHttpServer::Render render,
                      MetricsHttpServer::Ready ready) {
  http.Get("/metrics",
           [render = std::move(render)](const httplib::Request&, httplib::Response& response) {
             response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
           });
  http.Get("/healthz", [](const httplib::Request&, httplib::Response& response) {
    response.set_content("ok\n", kText);
  });
  http.Get("/readyz",
           [ready = std::move(ready)](const httplib::Request&, httplib::Response& response) {
             const auto [is_ready, reason] = ready();
             response.status = is_ready ? 200 : 503;
             response.set_content(is_ready ? "ready\n" : "not ready: " + reason + "\n", kText);
           });
  http.Get("/", [](const httplib::Request&, httplib::Response& response) {
    response.set_content(
        "forestmapd\n/metrics  Prometheus metrics\n/healthz  liveness\n/readyz   readiness\n",
        kText);
  });
}

MetricsHttpServer::MetricsHttpServer(const std::string& address, Render render, Ready ready,
                                     const HttpsSetup& https)
    : listener_("--metrics", address, https, [&](httplib::Server& http) {
        AddMetricsRoutes(http, std::move(render), std::move(ready));
      }) {}

}  // namespace forestmap::server
