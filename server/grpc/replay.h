#pragma once
// Exactly-once writes of the gRPC service (server/app/exactly_once.h) with their answers as
// messages: a call's request id is bound to its RPC, map, caller and request content; the stored
// answer of a repeated request is parsed into the call's response, and the call's deadline goes
// into the store with the write.

#include <google/protobuf/message_lite.h>
#include <grpcpp/grpcpp.h>

#include <string>

#include "server/app/exactly_once.h"
#include "server/ops/auth.h"
#include "storage/map_store.h"

namespace forestmap::server {

// SHA-256 (hex) of the deterministic serialization of `message` (map fields in key order).
std::string ContentDigest(const google::protobuf::MessageLite& message);

// The write of a call of `rpc` by `caller` to `map` with request id `id` and content digest
// `content_digest` (ContentDigest of the request), and the call's deadline (none when `context`
// is null).
WriteCall WriteCallOf(const grpc::CallbackServerContext* context, const Caller& caller,
                      const char* rpc, const std::string& map, const std::string& id,
                      std::string content_digest);

// Parses the stored answer of request `id` into `response`; throws std::runtime_error when it
// cannot be decoded.
void ParseStoredAnswer(const std::string& id, const std::string& stored,
                       google::protobuf::MessageLite& response);

// When `call`'s id was answered before for the same request, parses that answer into `response`
// and returns true. An id used for another request is a ValidationError (StoredAnswer).
bool ReplayRequest(storage::MapStore& store, const WriteCall& call,
                   google::protobuf::MessageLite& response);

// WriteExactlyOnce for a call: a repeated request is answered from the store into `response`
// without running `write` (and so is the loser of two concurrent calls with the same id).
template <typename Encode, typename Write>
void RunExactlyOnce(storage::MapStore& store, const WriteCall& call,
                    google::protobuf::MessageLite& response, Encode encode, Write write) {
  const std::optional<std::string> stored = WriteExactlyOnce(store, call, encode, write);
  if (stored) ParseStoredAnswer(call.request_id, *stored, response);
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
