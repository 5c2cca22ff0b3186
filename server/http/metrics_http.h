#pragma once
// The HTTP endpoint of forestmapd's metrics (--metrics ADDR): GET /metrics answers the
// Prometheus text exposition; anything else 404. Plain HTTP on its own port (cpp-httplib), so
// bind it to loopback or a monitoring network.
// Thread-safety: the constructor starts a thread that serves until the destructor stops it.

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
}  // namespace httplib

namespace forestmap::server {

class MetricsHttpServer {
 public:
  using Render = std::function<std::string()>;

  // Binds `address` ("host:port"; port 0 picks a free one) and serves `render()` on /metrics.
  // Throws std::runtime_error when the address cannot be bound or is malformed.
  MetricsHttpServer(const std::string& address, Render render);
  ~MetricsHttpServer();  // stops serving and joins the thread
  MetricsHttpServer(const MetricsHttpServer&) = delete;
  MetricsHttpServer& operator=(const MetricsHttpServer&) = delete;

  int port() const { return port_; }

 private:
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::atomic<bool> stopped_{false};
  std::thread thread_;
};

}  // namespace forestmap::server
