#pragma once
// Exactly-once writes (issue 15): a write RPC with a client request id is applied at most once;
// a repeat of the id gets the first answer, stored in the database in the same transaction as
// the write (storage/write_request.h). Every write also carries the call's deadline into the
// store, which refuses to commit once it has passed (DEADLINE_EXCEEDED, nothing written).

#include <google/protobuf/message_lite.h>
#include <grpcpp/grpcpp.h>

#include <string>

#include "server/grpc/status.h"
#include "storage/map_store.h"

namespace forestmap::server {

inline constexpr size_t kMaxRequestIdLength = 128;  // bytes

// An id is empty (none) or 1..128 printable ASCII characters (0x21..0x7e): ValidationError
// naming `field` otherwise.
void ValidateRequestId(const std::string& id, const std::string& field = "request_id");

// When `id` was answered before, parses that answer into `response` and returns true. An id
// answered for another RPC is a ValidationError.
bool ReplayRequest(storage::MapStore& store, const std::string& id, const char* rpc,
                   google::protobuf::MessageLite& response);

// Runs `write` (which calls the store's write methods on this thread) under a WriteRequestScope
// of the call's request id and deadline; `encode(info)` gives the bytes of the answer stored
// with the write. A repeated id is answered from the store into `response` without running
// `write` (and so is the loser of two concurrent calls with the same id).
template <typename Encode, typename Write>
void RunExactlyOnce(storage::MapStore& store, const grpc::CallbackServerContext* context,
                    const std::string& id, const char* rpc, google::protobuf::MessageLite& response,
                    Encode encode, Write write) {
  ValidateRequestId(id);
  if (!id.empty() && ReplayRequest(store, id, rpc, response)) return;
  storage::WriteRequest request;
  request.id = id;
  request.rpc = rpc;
  request.encode = encode;
  if (context != nullptr) request.deadline = context->deadline();
  const storage::WriteRequestScope scope(request);
  try {
    write();
  } catch (const storage::StorageError& e) {
    if (e.code() != storage::StorageError::Code::kConflict || id.empty() ||
        !ReplayRequest(store, id, rpc, response)) {
      throw;
    }
  }
}

// The encoder of a response that is a function of the map's info only.
template <typename Response, typename Fill>
auto Encoder(Fill fill) {
  return [fill](const storage::MapInfo& info) {
    Response response;
    fill(info, response);
    return response.SerializeAsString();
  };
}

}  // namespace forestmap::server
