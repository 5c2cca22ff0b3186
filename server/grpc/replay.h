#pragma once
// Exactly-once writes of the gRPC service (server/app/exactly_once.h) with their answers as
// messages: the stored answer of a repeated request id is parsed into the call's response, and
// the call's deadline goes into the store with the write.

#include <google/protobuf/message_lite.h>
#include <grpcpp/grpcpp.h>

#include <string>

#include "server/app/exactly_once.h"
#include "storage/map_store.h"

namespace forestmap::server {

// The write of a call: its request id, `rpc` and the call's deadline (none when `context` is
// null).
WriteCall WriteCallOf(const grpc::CallbackServerContext* context, const std::string& id,
                      const char* rpc);

// Parses the stored answer of request `id` into `response`; throws std::runtime_error when it
// cannot be decoded.
void ParseStoredAnswer(const std::string& id, const std::string& stored,
                       google::protobuf::MessageLite& response);

// When `id` was answered before, parses that answer into `response` and returns true. An id
// answered for another RPC is a ValidationError.
bool ReplayRequest(storage::MapStore& store, const std::string& id, const char* rpc,
                   google::protobuf::MessageLite& response);

// WriteExactlyOnce for a call: a repeated id is answered from the store into `response` without
// running `write` (and so is the loser of two concurrent calls with the same id).
template <typename Encode, typename Write>
void RunExactlyOnce(storage::MapStore& store, const grpc::CallbackServerContext* context,
                    const std::string& id, const char* rpc, google::protobuf::MessageLite& response,
                    Encode encode, Write write) {
  const std::optional<std::string> stored =
      WriteExactlyOnce(store, WriteCallOf(context, id, rpc), encode, write);
  if (stored) ParseStoredAnswer(id, *stored, response);
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
