#include "server/grpc/authorize.h"

#include <optional>

#include "server/grpc/rpc_observer.h"

namespace forestmap::server {

Caller Authorize(const Authorizer* authorizer, const grpc::ServerContextBase& context,
                 std::string_view rpc, std::string_view map) {
  if (authorizer == nullptr) {
    NoteCallMap(context, map, 0);
    return Caller{};
  }
  std::optional<std::string_view> authorization;
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  if (it != metadata.end()) authorization.emplace(it->second.data(), it->second.size());
  Caller caller = authorizer->Authenticate(authorization);
  NoteCallMap(context, map, caller.token ? caller.token->id : 0);
  Require(caller, rpc, map);
  return caller;
}

}  // namespace forestmap::server
