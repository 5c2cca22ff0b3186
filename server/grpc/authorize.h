#pragma once
// The token check of a gRPC call (server/ops/auth.h): the "authorization" metadata of the call
// through the server's Authorizer, and the map and token noted for the call's log line
// (server/grpc/rpc_observer.h). The one helper every handler calls first.

#include <grpcpp/grpcpp.h>

#include <string_view>

#include "server/ops/auth.h"

namespace forestmap::server {

// Authenticates the call on `context` through `authorizer` (null: open, every call allowed),
// notes `map` and the token for the log line, then requires the role `rpc` needs on `map`
// (empty: not about one map). Throws ServiceError kUnauthenticated or kPermissionDenied.
Caller Authorize(const Authorizer* authorizer, const grpc::ServerContextBase& context,
                 std::string_view rpc, std::string_view map);

}  // namespace forestmap::server
