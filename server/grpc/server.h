#pragma once
// Starting and stopping a gRPC server around a service, for forestmapd and for the tests.
// The server has the standard health service (grpc.health.v1.Health, SERVING for "" and every
// registered service while running) and server reflection, and refuses messages over the
// receive limit with RESOURCE_EXHAUSTED (gRPC does that before the service sees them).
// Thread-safety: Shutdown may be called from any thread, also while another thread is in Wait.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <mutex>
#include <string>

namespace forestmap::server {

class Metrics;

struct ServerOptions {
  int max_receive_message_bytes = 64 << 20;  // bytes per incoming message (1 .. 2^31-1)
  bool reflection = true;                    // grpc.reflection.v1alpha.ServerReflection
  // Transport security (server/ops/tls.h); null: plaintext.
  std::shared_ptr<grpc::ServerCredentials> credentials;
  // One log line per RPC and the RPC metrics (server/grpc/rpc_observer.h).
  bool observe_rpcs = true;
  Metrics* metrics = nullptr;  // RPC counts and latencies go here when set; must outlive the server
  // The health service's answer once started: SERVING, or NOT_SERVING until SetServing says
  // otherwise (forestmapd's health monitor, server/ops/health.h, decides it then).
  bool serving_at_start = true;
  void Check() const;  // throws std::invalid_argument
};

class ServerRunner {
 public:
  // Binds `address` ("host:port"; port 0 picks a free port) with options.credentials (default
  // plaintext), registers the
  // services and starts serving. Throws std::runtime_error if the address cannot be bound,
  // std::invalid_argument for invalid options. `service` must outlive the runner.
  ServerRunner(const std::string& address, grpc::Service& service,
               const ServerOptions& options = {});
  ~ServerRunner();  // Shutdown(), then waits for the server to stop
  ServerRunner(const ServerRunner&) = delete;
  ServerRunner& operator=(const ServerRunner&) = delete;

  int port() const { return port_; }  // the bound port (the selected one for 0)
  const std::string& address() const { return address_; }  // host:port actually bound

  // Sets the gRPC health status (grpc.health.v1.Health) of `service`: "" is the whole server;
  // any other name a client may ask for (forestmapd adds one per preloaded map). Ignored after
  // Shutdown, which marks everything NOT_SERVING for good.
  void SetServing(const std::string& service, bool serving);

  // Marks the server NOT_SERVING, stops accepting calls and waits up to `grace` for running
  // calls to finish before cancelling them. Idempotent.
  void Shutdown(std::chrono::milliseconds grace = std::chrono::seconds(5));
  // Blocks until the server has shut down.
  void Wait();

 private:
  std::unique_ptr<grpc::Server> server_;
  int port_ = 0;
  std::string address_;
  std::once_flag shutdown_once_;
  std::mutex health_mutex_;  // SetServing vs Shutdown
  bool shut_down_ = false;
};

}  // namespace forestmap::server
