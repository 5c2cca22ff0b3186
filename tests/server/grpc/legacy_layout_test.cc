// The wire layouts of release 0.1.0 the server still reads (server/legacy_layout.h): messages
// built with the deprecated fields, as an older client sends them, through the validators and
// through a real in-process server.

#include "server/grpc/legacy_layout.h"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "server/grpc/convert.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/grpc/upload_validator.h"
#include "server/grpc/validation.h"
#include "storage/sqlite/store.h"
#include "tests/server/grpc/validation_test_util.h"
#include "tests/server/rpc_test_support.h"

// Old clients set these fields; so do these tests.
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

using test::BadField;

v1::UploadTreesRequest OldUpload(const std::string& name, int first_id, int count) {
  v1::UploadTreesRequest message;
  message.set_name(name);
  for (int i = 0; i < count; ++i) {
    v1::Tree* tree = message.add_trees();
    tree->set_id(first_id + i);
    tree->set_x(i);
    tree->set_y(i);
  }
  return message;
}

TEST(LegacyLayoutTest, OldUploadStreamsAreRead) {
  UploadValidator validator(1000);
  v1::UploadTreesRequest first = OldUpload("plot", 0, 10);
  first.set_replace(true);
  first.set_request_id("retry-7");
  EXPECT_EQ(validator.Accept(first).size(), 10);           // the first message holds trees too
  v1::UploadTreesRequest unnamed = OldUpload("", 10, 10);  // later ones may omit the name
  EXPECT_EQ(validator.Accept(unnamed).size(), 10);
  v1::UploadTreesRequest named = OldUpload("plot", 20, 10);  // or repeat it
  named.set_request_id("retry-7");                           // and the request id
  EXPECT_EQ(validator.Accept(named).size(), 10);
  validator.Finish();
  EXPECT_EQ(validator.header().name(), "plot");
  EXPECT_TRUE(validator.header().replace());
  EXPECT_EQ(validator.header().request_id(), "retry-7");
  EXPECT_EQ(validator.trees(), 30);
}

TEST(LegacyLayoutTest, OldUploadStreamErrors) {
  v1::UploadTreesRequest unnamed = OldUpload("", 0, 1);
  EXPECT_EQ(BadField([&] { UploadValidator(10).Accept(unnamed); }), "name");
  UploadValidator validator(100);
  v1::UploadTreesRequest first = OldUpload("plot", 0, 1);
  validator.Accept(first);
  v1::UploadTreesRequest other = OldUpload("other", 1, 1);
  EXPECT_EQ(BadField([&] { validator.Accept(other); }), "name");
  v1::UploadTreesRequest replace = OldUpload("", 1, 1);
  replace.set_replace(true);
  EXPECT_EQ(BadField([&] { validator.Accept(replace); }), "replace");
  v1::UploadTreesRequest create = OldUpload("", 1, 1);
  create.set_crs("EPSG:2959");
  EXPECT_EQ(BadField([&] { validator.Accept(create); }), "crs");
  // One layout per message: 0.1.0 fields beside a header or chunk are refused.
  v1::UploadTreesRequest mixed = OldUpload("plot", 0, 1);
  mixed.mutable_header()->set_name("plot");
  EXPECT_EQ(BadField([&] { UploadValidator(10).Accept(mixed); }), "header");
}

TEST(LegacyLayoutTest, OldTrackStreamsAreRead) {
  v1::TrackRequest first;
  first.set_name("plot");
  first.set_frame_id(4);
  first.add_trees()->mutable_position()->set_x(1);
  first.set_client_stamp_ns(99);
  EXPECT_EQ(FrameIdOf(first), 4);
  const TrackMessage read = ReadTrackMessage(first, "", 100);
  EXPECT_EQ(read.map, "plot");
  ASSERT_TRUE(read.frame);  // the first message is also a frame, and answered
  EXPECT_EQ(read.frame->frame_id(), 4);
  EXPECT_EQ(read.frame->trees_size(), 1);
  EXPECT_EQ(read.frame->client_stamp_ns(), 99);

  v1::TrackRequest later;
  later.set_frame_id(5);
  EXPECT_EQ(ReadTrackMessage(later, "plot", 100).frame->frame_id(), 5);
  v1::TrackRequest elsewhere;
  elsewhere.set_name("other");
  EXPECT_EQ(BadField([&] { ReadTrackMessage(elsewhere, "plot", 100); }), "name");
  v1::TrackRequest mixed;
  mixed.set_frame_id(6);
  mixed.mutable_frame()->set_frame_id(6);
  EXPECT_EQ(BadField([&] { ReadTrackMessage(mixed, "plot", 100); }), "frame");
}

TEST(LegacyLayoutTest, OldPriorPoseGivesTheSamePrior) {
  v1::RelocalizeRequest old;
  old.set_name("plot");
  old.mutable_prior()->set_radius_m(12);
  *old.mutable_prior()->mutable_map_from_sensor() =
      ToProto(algorithms::PoseFromXyzYaw(5, 6, 1, 0.7));
  EXPECT_NO_THROW(Validate(old, 100));
  v1::RelocalizeRequest current = old;
  current.mutable_prior()->clear_map_from_sensor();
  current.mutable_prior()->set_x(5);
  current.mutable_prior()->set_y(6);
  const algorithms::PriorPose from_old = *FromProto(old).prior;
  const algorithms::PriorPose from_current = *FromProto(current).prior;
  // What the relocalizer reads of a prior: the horizontal position and the radius.
  EXPECT_EQ(from_old.map_from_sensor.translation().head<2>(),
            from_current.map_from_sensor.translation().head<2>());
  EXPECT_EQ(from_old.radius, from_current.radius);

  v1::RelocalizeRequest both = old;
  both.mutable_prior()->set_x(5);
  both.mutable_prior()->set_y(6);
  EXPECT_EQ(BadField([&] { Validate(both, 100); }), "prior.map_from_sensor");
  v1::RelocalizeRequest bad_rotation = old;
  bad_rotation.mutable_prior()->mutable_map_from_sensor()->mutable_rotation()->set_w(3);
  EXPECT_EQ(BadField([&] { Validate(bad_rotation, 100); }), "prior.map_from_sensor.rotation");
}

TEST(LegacyLayoutTest, PruneRequestIdOfField3IsAnAliasOfField50) {
  v1::PruneVersionsRequest request;
  EXPECT_EQ(RequestId(request), "");
  request.set_deprecated_request_id("old");
  EXPECT_EQ(RequestId(request), "old");
  request.set_request_id("old");
  EXPECT_EQ(RequestId(request), "old");
  request.clear_deprecated_request_id();
  EXPECT_EQ(RequestId(request), "old");
  request.set_deprecated_request_id("other");
  EXPECT_EQ(BadField([&] { RequestId(request); }), "deprecated_request_id");
}

// Through a real server: what a 0.1.0 client sends still works.
class LegacyServiceTest : public ::testing::Test {
 protected:
  std::unique_ptr<grpc::ClientContext> Context() {
    return test::CallContext(std::chrono::seconds(20));
  }
  v1::Map CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    EXPECT_TRUE(stub_->CreateMap(Context().get(), request, &map).ok());
    return map;
  }

  // One tree (id `id`) in one message of the 0.1.0 layout.
  grpc::Status UploadOld(const std::string& name, int id) {
    v1::UploadTreesResponse response;
    auto context = Context();
    auto writer = stub_->UploadTrees(context.get(), &response);
    writer->Write(OldUpload(name, id, 1));
    writer->WritesDone();
    return writer->Finish();
  }

  storage::SqliteMapStore store_{":memory:"};
  ForestMapService service_{store_, ServiceOptions{}};
  ServerRunner runner_{"127.0.0.1:0", service_};
  std::unique_ptr<v1::ForestMap::Stub> stub_ = v1::ForestMap::NewStub(
      grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()));
};

TEST_F(LegacyServiceTest, OldUploadAndTrackStreamsWork) {
  CreateMap("plot");
  v1::UploadTreesResponse uploaded;
  auto context = Context();
  auto writer = stub_->UploadTrees(context.get(), &uploaded);
  ASSERT_TRUE(writer->Write(OldUpload("plot", 0, 30)));  // the map and trees in one message
  ASSERT_TRUE(writer->Write(OldUpload("", 30, 30)));
  writer->WritesDone();
  ASSERT_TRUE(writer->Finish().ok());
  EXPECT_EQ(uploaded.trees_received(), 60);
  EXPECT_EQ(uploaded.map().tree_count(), 60);

  auto track_context = Context();
  auto stream = stub_->Track(track_context.get());
  for (int frame = 0; frame < 3; ++frame) {  // every message a frame, each answered
    v1::TrackRequest request;
    if (frame == 0) request.set_name("plot");
    request.set_frame_id(frame);
    ASSERT_TRUE(stream->Write(request));
    v1::TrackResponse response;
    ASSERT_TRUE(stream->Read(&response));
    EXPECT_EQ(response.frame_id(), frame);
    EXPECT_EQ(response.state(), v1::TrackResponse::STATE_LOST);  // no trees seen
  }
  stream->WritesDone();
  EXPECT_TRUE(stream->Finish().ok());
}

TEST_F(LegacyServiceTest, PruneRequestIdInField3IsTheRequestIdOfField50) {
  CreateMap("plot");
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(UploadOld("plot", i).ok());  // versions 2..4
  v1::PruneVersionsRequest old;
  old.set_name("plot");
  old.set_keep(1);
  old.set_deprecated_request_id("prune-1");
  v1::PruneVersionsResponse first;
  ASSERT_TRUE(stub_->PruneVersions(Context().get(), old, &first).ok());
  EXPECT_EQ(first.versions_removed(), 3);
  for (int i = 3; i < 5; ++i) ASSERT_TRUE(UploadOld("plot", i).ok());  // versions 5, 6

  // The same write retried by a newer client, with the id in field 50: answered from the first
  // call, nothing pruned again (a new id would remove versions 4 and 5).
  v1::PruneVersionsRequest retry = old;
  retry.clear_deprecated_request_id();
  retry.set_request_id("prune-1");
  v1::PruneVersionsResponse second;
  ASSERT_TRUE(stub_->PruneVersions(Context().get(), retry, &second).ok());
  EXPECT_EQ(second.versions_removed(), 0);
  EXPECT_EQ(store_.ListVersions("plot", 0).size(), 3u);  // 4, 5, 6

  v1::RemoveSourceRequest other_rpc;  // the id is taken, by PruneVersions
  other_rpc.set_name("plot");
  other_rpc.set_source("drone");
  other_rpc.set_request_id("prune-1");
  v1::RemoveSourceResponse ignored;
  const grpc::Status status = stub_->RemoveSource(Context().get(), other_rpc, &ignored);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("was already used for a PruneVersions call"));
}

}  // namespace
}  // namespace forestmap::server
