#include "server/http/metrics_http.h"

#include <httplib.h>

#include <memory>
#include <utility>

namespace forestmap::server {
namespace {

std::unique_ptr<httplib::Server> MetricsRoute(MetricsHttpServer::Render render) {
  auto http = std::make_unique<httplib::Server>();
  http->Get("/metrics",
            [render = std::move(render)](const httplib::Request&, httplib::Response& response) {
              response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
            });
  return http;
}

}  // namespace

MetricsHttpServer::MetricsHttpServer(const std::string& address, Render render)
    : listener_(MetricsRoute(std::move(render)), "--metrics", address) {}

}  // namespace forestmap::server
