#include "server/grpc/server.h"

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>

#include <climits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "forestmap/v1/forestmap_service.grpc.pb.h"
#include "server/grpc/decode_guard.h"
#include "server/grpc/rpc_observer.h"

namespace forestmap::server {
namespace {

// Both are process-wide switches that must be set before a ServerBuilder is created.
void InitGrpcPlugins(bool reflection) {
  static std::once_flag health_once;
  std::call_once(health_once, [] { grpc::EnableDefaultHealthCheckService(true); });
  if (reflection) {
    static std::once_flag reflection_once;
    std::call_once(reflection_once,
                   [] { grpc::reflection::InitProtoReflectionServerBuilderPlugin(); });
  }
}

// "host:port" with the port replaced by the bound one (for port 0).
std::string BoundAddress(const std::string& address, int port) {
  const size_t colon = address.rfind(':');
  const std::string host = colon == std::string::npos ? address : address.substr(0, colon);
  return host + ":" + std::to_string(port);
}

}  // namespace

void ServerOptions::Check() const {
  if (max_receive_message_bytes < 1) {
    throw std::invalid_argument("ServerOptions.max_receive_message_bytes must be >= 1");
  }
}

ServerRunner::ServerRunner(const std::string& address, grpc::Service& service,
                           const ServerOptions& options) {
  options.Check();
  InitGrpcPlugins(options.reflection);
  grpc::ServerBuilder builder;
  builder.AddListeningPort(
      address, options.credentials ? options.credentials : grpc::InsecureServerCredentials(),
      &port_);
  // The decode guard first: the observer then logs the status it made.
  std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> observers;
  observers.push_back(std::make_unique<DecodeGuardFactory>());
  if (options.observe_rpcs) {
    observers.push_back(std::make_unique<RpcObserverFactory>(options.metrics));
  }
  builder.experimental().SetInterceptorCreators(std::move(observers));
  builder.RegisterService(&service);
  builder.SetMaxReceiveMessageSize(options.max_receive_message_bytes);
  // gRPC sets SO_REUSEPORT by default, which lets a second server bind the same port and
  // silently receive part of the connections. One port, one server.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  server_ = builder.BuildAndStart();
  if (server_ == nullptr || port_ == 0) {
    if (server_ != nullptr) server_->Shutdown();
    throw std::runtime_error("cannot listen on " + address +
                             " (address in use, not local, or malformed?)");
  }
  address_ = BoundAddress(address, port_);
  SetServing("", options.serving_at_start);
}

void ServerRunner::SetServing(const std::string& service, bool serving) {
  std::lock_guard<std::mutex> lock(health_mutex_);
  grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService();
  if (health == nullptr || shut_down_) return;
  health->SetServingStatus(service, serving);
  // The service's own name answers as the whole server does.
  if (service.empty()) health->SetServingStatus(v1::ForestMap::service_full_name(), serving);
}

ServerRunner::~ServerRunner() {
  Shutdown();
  Wait();
}

void ServerRunner::Shutdown(std::chrono::milliseconds grace) {
  std::call_once(shutdown_once_, [&] {
    {
      std::lock_guard<std::mutex> lock(health_mutex_);
      shut_down_ = true;
      grpc::HealthCheckServiceInterface* health = server_->GetHealthCheckService();
      if (health != nullptr) health->SetServingStatus(false);
    }
    server_->Shutdown(std::chrono::system_clock::now() + grace);
  });
}

void ServerRunner::Wait() { server_->Wait(); }

}  // namespace forestmap::server
