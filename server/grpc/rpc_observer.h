#pragma once
// Watches every RPC of the server (a gRPC server interceptor): gives it a request id (the
// client's "x-request-id" metadata when it sends a usable one, else a random one; returned to the
// client in the initial metadata), and when the status is sent writes the RPC's log line
// (server/ops/logging.h: rpc, request_id, map, token, code, ms, peer, and the message of an error)
// and updates the metrics (server/ops/metrics.h). Handlers tell it the map a call is about through
// NoteCallMap (server/ops/auth.cc does, for every RPC).
//
// Thread-safety: all functions may be called concurrently.

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/server_interceptor.h>

#include <cstdint>
#include <string>
#include <string_view>

namespace forestmap::server {

class Metrics;

inline constexpr const char* kRequestIdHeader = "x-request-id";
inline constexpr size_t kMaxRequestIdBytes = 128;  // longer client ids are replaced

class RpcObserverFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  // `metrics` may be null (no metrics); else it must outlive the server.
  explicit RpcObserverFactory(Metrics* metrics) : metrics_(metrics) {}
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;

 private:
  Metrics* metrics_;
};

// Records, for the log line of the call running on `context`, the map it is about and the id of
// the token it used (0: none). No-op for a context without an observer (a server built without
// one).
void NoteCallMap(const grpc::ServerContextBase& context, std::string_view map, int64_t token_id);

}  // namespace forestmap::server
