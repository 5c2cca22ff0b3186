#include "server/http/metrics_http.h"

#include <httplib.h>

#include <chrono>

#include "server/http/http_listen.h"

namespace forestmap::server {
namespace {

constexpr auto kStopPoll = std::chrono::milliseconds(5);  // while waiting for the listen loop

}  // namespace

MetricsHttpServer::MetricsHttpServer(const std::string& address, Render render)
    : http_(std::make_unique<httplib::Server>()) {
  http_->Get("/metrics", [render](const httplib::Request&, httplib::Response& response) {
    response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
  });
  port_ = BindHttpListener(*http_, "--metrics", address);
  thread_ = std::thread([this] {
    http_->listen_after_bind();
    stopped_ = true;
  });
}

MetricsHttpServer::~MetricsHttpServer() {
  // stop() is a no-op until the listen loop runs: repeat it until the loop has ended.
  while (!stopped_) {
    http_->stop();
    std::this_thread::sleep_for(kStopPoll);
  }
  thread_.join();
}

}  // namespace forestmap::server
