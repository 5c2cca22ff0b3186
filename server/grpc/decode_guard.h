#pragma once
// Requests that cannot be decoded: gRPC answers a unary or server-streaming call whose
// request message fails to parse with UNIMPLEMENTED and no message (its callback handler cannot
// build the call), which reads as a missing method. This server interceptor notices the failed
// parse (the request it sees is null) and replaces that status with INVALID_ARGUMENT naming the
// RPC (server/grpc/status.h, UndecodableRequest). Streams from the client (UploadTrees, Track)
// check each message themselves.
//
// Thread-safety: gRPC calls an interceptor from one thread at a time; the factory is stateless.

#include <grpcpp/grpcpp.h>
#include <grpcpp/support/server_interceptor.h>

namespace forestmap::server {

class DecodeGuardFactory final : public grpc::experimental::ServerInterceptorFactoryInterface {
 public:
  grpc::experimental::Interceptor* CreateServerInterceptor(
      grpc::experimental::ServerRpcInfo* info) override;
};

}  // namespace forestmap::server
