#include "server/grpc/replay.h"

#include <optional>
#include <stdexcept>

namespace forestmap::server {

WriteCall WriteCallOf(const grpc::CallbackServerContext* context, const std::string& id,
                      const char* rpc) {
  WriteCall call;
  call.request_id = id;
  call.rpc = rpc;
  if (context != nullptr) call.deadline = context->deadline();
  return call;
}

void ParseStoredAnswer(const std::string& id, const std::string& stored,
                       google::protobuf::MessageLite& response) {
  if (!response.ParseFromString(stored)) {
    throw std::runtime_error("the stored answer of request id '" + id + "' cannot be decoded");
  }
}

bool ReplayRequest(storage::MapStore& store, const std::string& id, const char* rpc,
                   google::protobuf::MessageLite& response) {
  const std::optional<std::string> stored = StoredAnswer(store, id, rpc);
  if (!stored) return false;
  ParseStoredAnswer(id, *stored, response);
  return true;
}

}  // namespace forestmap::server
