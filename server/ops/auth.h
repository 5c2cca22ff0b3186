#pragma once
// Who may call what: bearer tokens with a role per map (storage/token_store.h), checked in ONE
// place, Authorizer::Authorize, which every handler calls first (unary bodies before anything
// else, streams on their first message, when the map name is known).
//
// Required roles (admin includes write, write includes read):
//   read   GetMap, ListMaps (lists only the maps the token can read), ExportTrees, Relocalize,
//          Track, ListVersions
//   write  UploadTrees, Observe, RemoveSource
//   admin  CreateMap, DeleteMap, RestoreVersion (and, when they come, prune and token admin)
// A token is sent as gRPC metadata "authorization: Bearer <secret>".
//
// Open or closed: without a token store, or while the store has never held a token, every call
// is allowed (as before tokens existed). Once a token was created (revoked ones count), every
// call needs a valid token: none -> UNAUTHENTICATED, unknown or revoked -> UNAUTHENTICATED, too
// weak a role or another map -> PERMISSION_DENIED. The health and reflection services stay open.
//
// Thread-safety: all methods may be called concurrently.

#include <grpcpp/grpcpp.h>

#include <optional>
#include <string>
#include <string_view>

#include "storage/token_store.h"

namespace forestmap::server {

// The role an RPC of forestmap.v1.ForestMap needs (by method name, "CreateMap"); nullopt for a
// method this table does not know, which Authorize then refuses (deny by default).
std::optional<storage::Role> RequiredRole(std::string_view rpc);

// The caller of one RPC. `token` is unset in open mode (no tokens): everything is allowed.
struct Caller {
  std::optional<storage::TokenRecord> token;
  bool CanRead(std::string_view map) const;  // for filtering ListMaps
};

class Authorizer {
 public:
  // `tokens` null: open, every call allowed. Otherwise it must outlive the authorizer.
  explicit Authorizer(storage::TokenStore* tokens) : tokens_(tokens) {}

  // The caller of `context`'s RPC. Throws ServiceError UNAUTHENTICATED when tokens are in force
  // and the call carries none, a malformed one, or one that is unknown or revoked.
  Caller Authenticate(const grpc::ServerContextBase& context) const;

  // Authenticate, then require RequiredRole(rpc) on map `map`; throws ServiceError
  // UNAUTHENTICATED or PERMISSION_DENIED with a message naming the token id, its grant and what
  // was needed. `map` empty: the RPC is not about one map (ListMaps). Also notes `map` for the
  // RPC's log line (server/logging.h).
  Caller Authorize(const grpc::ServerContextBase& context, std::string_view rpc,
                   std::string_view map) const;

 private:
  storage::TokenStore* tokens_;
};

// Authorize through `authorizer` when it is set (ServiceOptions::authorizer); else only notes the
// map for the log. The one helper the handlers call.
Caller Authorize(const Authorizer* authorizer, const grpc::ServerContextBase& context,
                 std::string_view rpc, std::string_view map);

}  // namespace forestmap::server
