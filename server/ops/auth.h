#pragma once
// Who may call what: bearer tokens with a role per map (storage/token_store.h), checked in ONE
// place, Authorizer and Require, which every handler calls first through its transport (gRPC:
// server/grpc/authorize.h; unary bodies before anything else, streams as they open, for the role
// on some map, and on their first message for the map it names).
//
// Required roles (admin includes write, write includes read):
//   read   GetMap, ListMaps (lists only the maps the token can read), ExportTrees, Relocalize,
//          Track, ListVersions
//   write  UploadTrees, Observe, RemoveSource
//   admin  CreateMap, DeleteMap, RestoreVersion, PruneVersions
// A token is sent as gRPC metadata "authorization: Bearer <secret>" (the scheme in any case).
//
// Open or closed: without a token store, or while the store has never held a token, every call
// is allowed (as before tokens existed). Once a token was created (revoked ones count), every
// call needs a valid token: none -> UNAUTHENTICATED, unknown, revoked or expired ->
// UNAUTHENTICATED, too weak a role or another map -> PERMISSION_DENIED. The health and reflection
// services stay open.
//
// Thread-safety: all methods may be called concurrently.

#include <optional>
#include <string>
#include <string_view>

#include "storage/token_store.h"

namespace forestmap::server {

// The role an RPC of forestmap.v1.ForestMap needs (by method name, "CreateMap"); nullopt for a
// method this table does not know, which Require then refuses (deny by default).
std::optional<storage::Role> RequiredRole(std::string_view rpc);

// The caller of one RPC. `token` is unset in open mode (no tokens): everything is allowed.
struct Caller {
  std::optional<storage::TokenRecord> token;
  bool CanRead(std::string_view map) const;  // for filtering ListMaps
  std::string Name() const;                  // "token 7"; empty in open mode
};

// Requires RequiredRole(rpc) of `caller` on map `map` (empty: the RPC is not about one map,
// ListMaps); throws ServiceError kPermissionDenied with a message naming the token id, its grant
// and what was needed. An RPC the table does not know is refused even in open mode.
void Require(const Caller& caller, std::string_view rpc, std::string_view map);

class Authorizer {
 public:
  // `tokens` null: open, every call allowed. Otherwise it must outlive the authorizer.
  explicit Authorizer(storage::TokenStore* tokens) : tokens_(tokens) {}

  // The caller presenting `authorization`, the value of its "authorization" metadata (nullopt:
  // none). Throws ServiceError kUnauthenticated when tokens are in force and the call carries
  // none, a malformed one, or one that is unknown, revoked or expired.
  Caller Authenticate(std::optional<std::string_view> authorization) const;

 private:
  storage::TokenStore* tokens_;
};

}  // namespace forestmap::server
