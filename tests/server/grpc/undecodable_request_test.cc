// Undecodable request bytes of a unary RPC once got UNIMPLEMENTED (gRPC's own
// answer when it cannot parse a request), which reads as "no such method". Now every unary RPC
// and ExportTrees (one request message) answer INVALID_ARGUMENT naming the RPC, and the server
// keeps serving. Raw bytes go through grpc::GenericStub, as a broken or hostile client sends them.

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <string>
#include <string_view>
#include <vector>

#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

constexpr auto kUndecodableDeadline = std::chrono::seconds(20);  // turns a hang into a failure

// Bytes that are no protobuf message: a length-delimited field 1 announcing 5 bytes and holding
// 2, a varint longer than 10 bytes, and a string field 1 (every request but ListMaps' has one)
// that is not UTF-8.
const std::vector<std::string> kGarbage = {
    std::string("\x0a\x05"
                "ab",
                4),
    std::string(12, '\xff'),
    std::string("\x0a\x02\xc3\x28", 4),
};

constexpr const char* kPrefix = "/forestmap.v1.ForestMap/";
// Every RPC of the service with one request message but ExportTrees (server streaming); the
// table of server/ops/auth.cc lists them all, and a test there checks that it does.
constexpr const char* kUnaryRpcs[] = {
    "CreateMap", "ListMaps",     "GetMap",         "DeleteMap",    "Relocalize",
    "Observe",   "ListVersions", "RestoreVersion", "RemoveSource", "PruneVersions"};

grpc::ByteBuffer Bytes(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

class UndecodableRequestTest : public ::testing::Test {
 protected:
  UndecodableRequestTest()
      : store_(":memory:"),
        service_(store_, ServiceOptions{}),
        runner_("127.0.0.1:0", service_),
        channel_(grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials())),
        generic_(channel_) {}

  grpc::Status Unary(const std::string& method, const std::string& bytes) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + kUndecodableDeadline);
    const grpc::ByteBuffer request = Bytes(bytes);
    grpc::ByteBuffer response;
    std::promise<grpc::Status> done;
    generic_.UnaryCall(&context, method, grpc::StubOptions(), &request, &response,
                       [&done](grpc::Status status) { done.set_value(status); });
    return done.get_future().get();
  }

  // A server-streaming call with one request: the status after the last response.
  grpc::Status ServerStreaming(const std::string& method, const std::string& bytes) {
    grpc::CompletionQueue queue;
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + kUndecodableDeadline);
    auto call = generic_.PrepareCall(&context, method, &queue);
    void* tag = nullptr;
    bool ok = false;
    int next = 1;
    call->StartCall(reinterpret_cast<void*>(next++));
    queue.Next(&tag, &ok);
    call->WriteLast(Bytes(bytes), grpc::WriteOptions(), reinterpret_cast<void*>(next++));
    queue.Next(&tag, &ok);
    grpc::ByteBuffer response;
    do {
      call->Read(&response, reinterpret_cast<void*>(next++));
      queue.Next(&tag, &ok);
    } while (ok);
    grpc::Status status;
    call->Finish(&status, reinterpret_cast<void*>(next++));
    queue.Next(&tag, &ok);
    queue.Shutdown();
    while (queue.Next(&tag, &ok)) {
    }
    return status;
  }

  storage::SqliteMapStore store_;
  ForestMapService service_;
  ServerRunner runner_;
  std::shared_ptr<grpc::Channel> channel_;
  grpc::GenericStub generic_;
};

TEST_F(UndecodableRequestTest, EveryUnaryRpcAnswersInvalidArgumentAndTheServerKeepsServing) {
  for (const char* rpc : kUnaryRpcs) {
    for (const std::string& bytes : kGarbage) {
      // ListMapsRequest has no fields: its field 1 is an unknown field, skipped whatever it holds.
      if (std::string_view(rpc) == "ListMaps" && bytes == kGarbage.back()) continue;
      const grpc::Status status = Unary(std::string(kPrefix) + rpc, bytes);
      EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
          << rpc << ": " << status.error_code() << " " << status.error_message();
      EXPECT_NE(
          status.error_message().find(std::string("the ") + rpc + " request cannot be decoded"),
          std::string::npos)
          << status.error_message();
    }
  }
  for (const std::string& bytes : kGarbage) {
    const grpc::Status status = ServerStreaming(std::string(kPrefix) + "ExportTrees", bytes);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT)
        << "ExportTrees: " << status.error_code() << " " << status.error_message();
  }
  // Still serving: a well-formed call works.
  auto stub = v1::ForestMap::NewStub(channel_);
  grpc::ClientContext context;
  v1::CreateMapRequest request;
  request.set_name("after-garbage");
  v1::Map map;
  const grpc::Status created = stub->CreateMap(&context, request, &map);
  EXPECT_TRUE(created.ok()) << created.error_message();
  // An unknown method is still UNIMPLEMENTED: only undecodable requests change.
  EXPECT_EQ(Unary("/forestmap.v1.ForestMap/NoSuchMethod", "").error_code(),
            grpc::StatusCode::UNIMPLEMENTED);
}

}  // namespace
}  // namespace forestmap::server
