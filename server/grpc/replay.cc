#include "server/grpc/replay.h"

#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include <optional>
#include <stdexcept>
#include <utility>

#include "storage/token_store.h"

namespace forestmap::server {

std::string ContentDigest(const google::protobuf::MessageLite& message) {
  std::string bytes;
  {
    google::protobuf::io::StringOutputStream stream(&bytes);
    google::protobuf::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);
    message.SerializeToCodedStream(&coded);
  }
  return storage::Sha256Hex(bytes);
}

WriteCall WriteCallOf(const grpc::CallbackServerContext* context, const Caller& caller,
                      const char* rpc, const std::string& map, const std::string& id,
                      std::string content_digest) {
  WriteCall call;
  call.request_id = id;
  call.rpc = rpc;
  call.map = map;
  call.caller = caller.Name();
  call.content_digest = std::move(content_digest);
  if (context != nullptr) call.deadline = context->deadline();
  return call;
}

void ParseStoredAnswer(const std::string& id, const std::string& stored,
                       google::protobuf::MessageLite& response) {
  if (!response.ParseFromString(stored)) {
    throw std::runtime_error("the stored answer of request id '" + id + "' cannot be decoded");
  }
}

bool ReplayRequest(storage::MapStore& store, const WriteCall& call,
                   google::protobuf::MessageLite& response) {
  const std::optional<std::string> stored = StoredAnswer(store, call);
  if (!stored) return false;
  ParseStoredAnswer(call.request_id, *stored, response);
  return true;
}

}  // namespace forestmap::server
