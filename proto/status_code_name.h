#pragma once
// Names of gRPC status codes ("NOT_FOUND", ...) for messages and logs, shared by client and server.

#include <grpcpp/support/status.h>

namespace forestmap {

const char* StatusCodeName(grpc::StatusCode code) noexcept;

}  // namespace forestmap
