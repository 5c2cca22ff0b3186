// Structured error details (AIP-193): an INVALID_ARGUMENT of a request check carries a
// google.rpc.BadRequest naming the field beside its message, through a real in-process server,
// for unary calls and both client streams; other errors carry none.

#include "proto/error_details.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <limits>
#include <string>
#include <vector>

#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/server/grpc/validation_test_util.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

using test::kNaN;

// The fields of the status's BadRequest details; the description is the status message.
std::vector<std::string> BadFields(const grpc::Status& status) {
  std::vector<std::string> fields;
  for (const FieldViolation& violation : BadRequestViolations(status)) {
    EXPECT_EQ(violation.description, status.error_message());
    fields.push_back(violation.field);
  }
  return fields;
}

class ErrorDetailsTest : public ::testing::Test {
 protected:
  ErrorDetailsTest() {
    v1::CreateMapRequest request;
    request.set_name("plot");
    v1::Map map;
    EXPECT_TRUE(stub_->CreateMap(Context().get(), request, &map).ok());
  }
  std::unique_ptr<grpc::ClientContext> Context() {
    return test::CallContext(std::chrono::seconds(20));
  }

  storage::SqliteMapStore store_{":memory:"};
  ForestMapService service_{store_, ServiceOptions{}};
  ServerRunner runner_{"127.0.0.1:0", service_};
  std::unique_ptr<v1::ForestMap::Stub> stub_ = v1::ForestMap::NewStub(
      grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()));
};

TEST_F(ErrorDetailsTest, UnaryValidationFailuresNameTheirField) {
  v1::CreateMapRequest create;
  create.set_name("bad name!");
  v1::Map map;
  grpc::Status status = stub_->CreateMap(Context().get(), create, &map);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(BadFields(status), ElementsAre("name"));

  v1::RelocalizeRequest relocalize;
  relocalize.set_name("plot");
  for (int i = 0; i < 3; ++i) relocalize.add_trees()->mutable_position()->set_x(i);
  relocalize.mutable_trees(1)->mutable_position()->set_x(kNaN);
  v1::RelocalizeResponse answer;
  status = stub_->Relocalize(Context().get(), relocalize, &answer);
  EXPECT_EQ(status.error_message(), "trees[1].position.x is NaN; numbers must be finite");
  EXPECT_THAT(BadFields(status), ElementsAre("trees[1].position.x"));

  v1::ListMapsRequest list;
  list.set_page_token("garbage");
  v1::ListMapsResponse maps;
  status = stub_->ListMaps(Context().get(), list, &maps);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(BadFields(status), ElementsAre("page_token"));
}

TEST_F(ErrorDetailsTest, StreamValidationFailuresNameTheirField) {
  v1::UploadTreesResponse uploaded;
  auto context = Context();
  auto writer = stub_->UploadTrees(context.get(), &uploaded);
  v1::UploadTreesRequest header;
  header.mutable_header()->set_name("plot");
  writer->Write(header);
  v1::UploadTreesRequest chunk;
  chunk.mutable_chunk()->add_trees()->set_x(1);
  chunk.mutable_chunk()->add_trees()->set_dbh(-1);
  writer->Write(chunk);
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(BadFields(status), ElementsAre("trees[1].dbh"));

  auto track_context = Context();
  auto stream = stub_->Track(track_context.get());
  v1::TrackRequest track_header;
  track_header.mutable_header()->set_name("plot");
  stream->Write(track_header);
  v1::TrackRequest frame;
  frame.mutable_frame()->set_frame_id(12);
  frame.mutable_frame()->mutable_gravity();  // a zero vector
  stream->Write(frame);
  stream->WritesDone();
  v1::TrackResponse ignored;
  while (stream->Read(&ignored)) {
  }
  status = stream->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("frame 12: frame.gravity is a zero vector"));
  ASSERT_EQ(BadRequestViolations(status).size(), 1u);  // kept through the frame prefix
  EXPECT_EQ(BadRequestViolations(status)[0].field, "frame.gravity");
}

TEST_F(ErrorDetailsTest, OtherErrorsCarryNoBadRequest) {
  v1::GetMapRequest request;
  request.set_name("absent");
  v1::Map map;
  const grpc::Status status = stub_->GetMap(Context().get(), request, &map);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(BadRequestViolations(status).empty());
}

TEST(ErrorDetailsHelpersTest, RoundTripAndGarbage) {
  const grpc::Status status = StatusWithBadRequest(grpc::StatusCode::INVALID_ARGUMENT, "m",
                                                   {{"a.b[2]", "bad"}, {"c", "worse"}});
  const std::vector<FieldViolation> violations = BadRequestViolations(status);
  ASSERT_EQ(violations.size(), 2u);
  EXPECT_EQ(violations[1].field, "c");
  EXPECT_EQ(violations[1].description, "worse");
  EXPECT_TRUE(StatusWithBadRequest(grpc::StatusCode::NOT_FOUND, "m", {}).error_details().empty());
  const grpc::Status garbage(grpc::StatusCode::INVALID_ARGUMENT, "m", "\xff\x01 not a status");
  EXPECT_TRUE(BadRequestViolations(garbage).empty());
}

}  // namespace
}  // namespace forestmap::server
