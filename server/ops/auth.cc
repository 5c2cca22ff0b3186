#include "server/ops/auth.h"

#include <array>

#include "server/app/errors.h"

namespace forestmap::server {
namespace {

using storage::Role;

constexpr const char* kHowToPass =
    "pass one with --token or the environment variable FORESTMAP_TOKEN (gRPC metadata "
    "'authorization: Bearer <token>')";

struct RpcRole {
  std::string_view rpc;
  Role role;
};

// Every RPC of forestmap.v1.ForestMap. A new RPC must be added here, or it is refused.
constexpr std::array<RpcRole, 13> kRoles = {{
    {"CreateMap", Role::kAdmin},
    {"ListMaps", Role::kRead},
    {"GetMap", Role::kRead},
    {"DeleteMap", Role::kAdmin},
    {"UploadTrees", Role::kWrite},
    {"ExportTrees", Role::kRead},
    {"Relocalize", Role::kRead},
    {"Track", Role::kRead},
    {"Observe", Role::kWrite},
    {"ListVersions", Role::kRead},
    {"RestoreVersion", Role::kAdmin},
    {"RemoveSource", Role::kWrite},
    {"PruneVersions", Role::kAdmin},
}};

ServiceError Unauthenticated(const std::string& message) {
  return ServiceError(ErrorCode::kUnauthenticated, message);
}

std::string Describe(const storage::TokenRecord& token) {
  return "token " + std::to_string(token.id) + " (role " + storage::RoleName(token.role) +
         " on maps '" + token.map_pattern + "')";
}

}  // namespace

std::optional<Role> RequiredRole(std::string_view rpc) {
  for (const RpcRole& entry : kRoles) {
    if (entry.rpc == rpc) return entry.role;
  }
  return std::nullopt;
}

bool Caller::CanRead(std::string_view map) const {
  return !token || token->Allows(Role::kRead, map);
}

std::string Caller::Name() const {
  return token ? "token " + std::to_string(token->id) : std::string();
}

void Require(const Caller& caller, std::string_view rpc, std::string_view map) {
  const std::optional<Role> needed = RequiredRole(rpc);
  if (!needed) {
    throw ServiceError(ErrorCode::kPermissionDenied,
                       "no access rule for RPC " + std::string(rpc) + " (denied by default)");
  }
  if (!caller.token) return;
  const bool allowed = map.empty()
                           ? static_cast<int>(caller.token->role) >= static_cast<int>(*needed)
                           : caller.token->Allows(*needed, map);
  if (!allowed) {
    throw ServiceError(ErrorCode::kPermissionDenied,
                       Describe(*caller.token) + " may not call " + std::string(rpc) +
                           (map.empty() ? "" : " on map '" + std::string(map) + "'") +
                           ": that needs role " + storage::RoleName(*needed) + " on it");
  }
}

Caller Authorizer::Authenticate(std::optional<std::string_view> authorization) const {
  Caller caller;
  if (tokens_ == nullptr || !tokens_->AnyToken()) return caller;  // open: no token exists
  if (!authorization) {
    throw Unauthenticated(std::string("this server requires a token; ") + kHowToPass);
  }
  const std::string_view secret = storage::BearerSecret(*authorization);
  if (secret.empty()) {
    throw Unauthenticated("the authorization metadata must be 'Bearer <token>'");
  }
  caller.token = tokens_->Find(secret);
  if (!caller.token) throw Unauthenticated("unknown, revoked or expired token");
  return caller;
}

}  // namespace forestmap::server
