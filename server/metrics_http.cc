#include "server/metrics_http.h"

#include <httplib.h>

#include <chrono>
#include <stdexcept>

namespace forestmap::server {
namespace {

constexpr auto kStopPoll = std::chrono::milliseconds(5);  // while waiting for the listen loop

}  // namespace

MetricsHttpServer::MetricsHttpServer(const std::string& address, Render render)
    : http_(std::make_unique<httplib::Server>()) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos || colon == 0) {
    throw std::runtime_error("--metrics address must be host:port, not '" + address + "'");
  }
  std::string host = address.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);  // [::1]:9090
  }
  int port = -1;
  try {
    port = std::stoi(address.substr(colon + 1));
  } catch (const std::exception&) {
  }
  if (port < 0 || port > 65535) {
    throw std::runtime_error("--metrics address has no valid port: '" + address + "'");
  }
  http_->Get("/metrics", [render](const httplib::Request&, httplib::Response& response) {
    response.set_content(render(), "text/plain; version=0.0.4; charset=utf-8");
  });
  port_ = port == 0 ? http_->bind_to_any_port(host) : (http_->bind_to_port(host, port) ? port : -1);
  if (port_ <= 0) throw std::runtime_error("cannot listen for metrics on " + address);
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
