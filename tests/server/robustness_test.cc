// Issue 15 (robustness): findings that once crashed the server, cut uploads short, applied a
// retried write twice or let a fault look like a bug, each checked end to end through a real
// in-process gRPC server over a SQLite file.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "server/server.h"
#include "server/service.h"
#include "storage/sqlite_map_store.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

constexpr auto kCallDeadline = std::chrono::seconds(20);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> Context() {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + kCallDeadline);
  return context;
}

std::filesystem::path TestDir() {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      ("forestmap_robust_" + std::to_string(getpid()) + "_" +
       ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

v1::Tree TreeAt(double x, double y) {
  v1::Tree tree;
  tree.set_x(x);
  tree.set_y(y);
  return tree;
}

class RobustnessTest : public ::testing::Test {
 protected:
  RobustnessTest()
      : dir_(TestDir()),
        store_((dir_ / "maps.db").string()),
        service_(store_, ServiceOptions{}),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}
  ~RobustnessTest() override { std::filesystem::remove_all(dir_); }

  grpc::Status CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    return stub_->CreateMap(Context().get(), request, &map);
  }

  // Uploads `trees` in one message.
  grpc::Status Upload(const std::string& name, const std::vector<v1::Tree>& trees,
                      v1::UploadTreesResponse* response = nullptr) {
    v1::UploadTreesResponse ignored;
    auto context = Context();
    auto writer = stub_->UploadTrees(context.get(), response ? response : &ignored);
    v1::UploadTreesRequest message;
    message.set_map_name(name);
    for (const v1::Tree& tree : trees) *message.add_trees() = tree;
    writer->Write(message);
    writer->WritesDone();
    return writer->Finish();
  }

  grpc::Status Relocalize(const std::string& name) {
    v1::RelocalizeRequest request;
    request.set_map_name(name);
    for (auto [x, y] : {std::pair{0.0, 0.0}, {3.0, 0.0}, {0.0, 4.0}}) {
      v1::DetectedTree* tree = request.add_trees();
      tree->mutable_position()->set_x(x);
      tree->mutable_position()->set_y(y);
    }
    v1::RelocalizeResponse response;
    return stub_->Relocalize(Context().get(), request, &response);
  }

  void ExpectServing() {
    v1::ListMapsResponse response;
    const grpc::Status status = stub_->ListMaps(Context().get(), v1::ListMapsRequest(), &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }

  std::filesystem::path dir_;
  storage::SqliteMapStore store_;
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
};

// Finding 1: `map create far --trees far.csv` (a tree at x = 1e308) then `relocalize far`
// segfaulted the server, again after every restart.
TEST_F(RobustnessTest, FarTreeIsRejectedByNameAndNeverCrashesTheServer) {
  ASSERT_TRUE(CreateMap("far").ok());
  const std::vector<v1::Tree> far = {TreeAt(0, 0), TreeAt(3, 0), TreeAt(0, 4), TreeAt(1e308, 1)};
  grpc::Status status = Upload("far", far);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("trees[3].x is 1e+308"));

  // A map stored before ranges were validated (written past the service): the index build
  // fails, the map answers FAILED_PRECONDITION naming it, the server keeps serving.
  std::vector<storage::TreeRecord> records(4);
  records[1].x = 3, records[2].y = 4, records[3].x = 1e308;
  store_.WriteTrees("far", records, storage::WriteMode::kAppend);
  for (int attempt = 0; attempt < 2; ++attempt) {
    status = Relocalize("far");
    EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
    EXPECT_THAT(status.error_message(), HasSubstr("map \"far\""));
    EXPECT_THAT(status.error_message(), HasSubstr("cannot be indexed"));
  }
  EXPECT_EQ(service_.index_cache().stats().builds, 1);  // the failure is remembered
  ExpectServing();
}

TEST_F(RobustnessTest, FarObservationPoseIsRejectedByName) {
  ASSERT_TRUE(CreateMap("shared").ok());
  v1::ObserveRequest request;
  request.set_map_name("shared");
  request.set_source("drone1");
  v1::ObservationFrame* frame = request.add_frames();
  frame->mutable_map_from_sensor()->mutable_translation()->set_x(1e45);
  for (int i = 0; i < 3; ++i) frame->add_trees()->mutable_position()->set_x(2.0 * i);
  v1::ObserveResponse response;
  const grpc::Status status = stub_->Observe(Context().get(), request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(),
              HasSubstr("frames[0].map_from_sensor.translation.x is 1e+45"));
  ExpectServing();
}

// Finding 2: a non-UTF-8 attribute in message 3 of 5 made that message undecodable; the server
// took that as the end of the stream and committed the trees of messages 0..2.
TEST_F(RobustnessTest, UndecodableUploadMessageFailsTheUploadAndWritesNothing) {
  ASSERT_TRUE(CreateMap("plot").ok());
  v1::UploadTreesResponse response;
  auto context = Context();
  auto writer = stub_->UploadTrees(context.get(), &response);
  for (int m = 0; m < 5; ++m) {
    v1::UploadTreesRequest message;
    if (m == 0) message.set_map_name("plot");
    for (int i = 0; i < 1000; ++i) {
      v1::Tree tree = TreeAt(m * 1000 + i, i);
      if (m == 3 && i == 7)
        (*tree.mutable_attributes())["species"] =
            "\xe9pic\xe9"
            "a";
      *message.add_trees() = tree;
    }
    if (!writer->Write(message)) break;  // the server already answered
  }
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("upload message 3 (after 3000 trees)"));
  EXPECT_THAT(status.error_message(), HasSubstr("nothing was written"));
  EXPECT_EQ(store_.GetMap("plot").tree_count, 0);
  ExpectServing();
}

}  // namespace
}  // namespace forestmap::server
