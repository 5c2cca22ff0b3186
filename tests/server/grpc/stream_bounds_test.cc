// Bounded memory, writers per map and atomic create with trees, end to end through an
// in-process gRPC server over a SQLite file: uploads are staged in the database while they
// stream, other maps are written meanwhile, a cancelled create leaves no map and no staged rows,
// exports follow a slow reader page by page, and streams over their limit are RESOURCE_EXHAUSTED.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;
using Stub = v1::ForestMap::Stub;

constexpr auto kBoundsDeadline = std::chrono::seconds(60);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> BoundsContext() { return test::CallContext(kBoundsDeadline); }

std::filesystem::path BoundsTestDir() { return test::FreshTestDir("forestmap_bounds_"); }

// A chunk of `count` trees with ids first_id.. on a grid.
v1::UploadTreesRequest Chunk(int64_t first_id, int count) {
  v1::UploadTreesRequest message;
  for (int i = 0; i < count; ++i) {
    v1::Tree* tree = message.mutable_chunk()->add_trees();
    tree->set_id(first_id + i);
    tree->set_x(static_cast<double>((first_id + i) % 300));
    tree->set_y(static_cast<double>((first_id + i) / 300));
  }
  return message;
}

ServiceOptions Options() {
  ServiceOptions options;
  options.upload_stage_trees = 1000;
  options.export_chunk_trees = 500;
  options.streams.max_streams = 3;
  options.streams.max_streams_per_client = 2;
  return options;
}

class StreamBoundsTest : public ::testing::Test {
 protected:
  StreamBoundsTest()
      : dir_(BoundsTestDir()),
        path_((dir_ / "maps.db").string()),
        store_(path_),
        gated_(store_),
        service_(gated_, Options()),
        runner_("127.0.0.1:0", service_),
        stub_(NewStub()) {}
  ~StreamBoundsTest() override { std::filesystem::remove_all(dir_); }

  // A stub on its own connection: another client for the stream limits.
  std::unique_ptr<Stub> NewStub() {
    grpc::ChannelArguments arguments;
    arguments.SetInt("forestmap.test.unique", next_channel_++);  // no shared subchannel
    return v1::ForestMap::NewStub(grpc::CreateCustomChannel(
        runner_.address(), grpc::InsecureChannelCredentials(), arguments));
  }

  grpc::Status CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    return stub_->CreateMap(BoundsContext().get(), request, &map);
  }

  grpc::Status Upload(const std::string& name, int count, bool create = false,
                      bool replace = false) {
    v1::UploadTreesResponse response;
    auto context = BoundsContext();
    auto writer = stub_->UploadTrees(context.get(), &response);
    bool open = writer->Write(test::UploadHeader(name, replace, create));
    for (int sent = 0; open && sent < count; sent += 1000) {
      open = writer->Write(Chunk(sent + 1, std::min(1000, count - sent)));
    }
    writer->WritesDone();
    return writer->Finish();
  }

  v1::Map GetMap(const std::string& name, grpc::Status* status = nullptr) {
    v1::GetMapRequest request;
    request.set_name(name);
    v1::Map map;
    const grpc::Status got = stub_->GetMap(BoundsContext().get(), request, &map);
    if (status) *status = got;
    return map;
  }

  // Staged rows (pending ones, and the rows of maps being created) and open uploads in the
  // file, through another connection.
  int64_t Pending() {
    storage::sqlite::Database db(path_, SQLITE_OPEN_READONLY, 5000);
    return db.QueryInt64(
               "SELECT COUNT(*) FROM trees WHERE valid_to < 0 OR map_id IN (SELECT id "
               "FROM maps WHERE creating_upload IS NOT NULL)") +
           db.QueryInt64("SELECT COUNT(*) FROM uploads");
  }

  int next_channel_ = 0;
  std::filesystem::path dir_;
  std::string path_;
  storage::SqliteMapStore store_;
  GatedStore gated_;
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<Stub> stub_;
};

// Findings 3 and 5: the upload is in the database while it streams (not in the server's memory),
// and map B is created and written while A's upload is open and staged.
TEST_F(StreamBoundsTest, UploadIsStagedWhileItStreamsAndOtherMapsAreWrittenMeanwhile) {
  v1::UploadTreesResponse response;
  auto context = BoundsContext();
  auto writer = stub_->UploadTrees(context.get(), &response);
  constexpr int kMessages = 20;
  ASSERT_TRUE(writer->Write(test::UploadHeader("a", false, /*create_map=*/true)));
  for (int m = 0; m < kMessages; ++m) ASSERT_TRUE(writer->Write(Chunk(m * 1000 + 1, 1000)));
  // All but the last chunk are staged before the stream ends.
  ASSERT_TRUE(Eventually([&] { return Pending() >= (kMessages - 1) * 1000; })) << Pending();
  ASSERT_TRUE(CreateMap("b").ok());
  ASSERT_TRUE(Upload("b", 2500).ok());
  EXPECT_EQ(GetMap("b").tree_count(), 2500);
  grpc::Status status;
  GetMap("a", &status);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);  // not created before it commits

  writer->WritesDone();
  status = writer->Finish();
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.map().tree_count(), kMessages * 1000);
  EXPECT_EQ(GetMap("a").tree_count(), kMessages * 1000);
  EXPECT_EQ(Pending(), 0);
}

// Finding 7: `map create --trees` killed mid-upload left an empty map behind.
TEST_F(StreamBoundsTest, CancelledCreateWithTreesLeavesNoMapAndNoStagedRows) {
  {
    v1::UploadTreesResponse response;
    auto context = BoundsContext();
    auto writer = stub_->UploadTrees(context.get(), &response);
    ASSERT_TRUE(writer->Write(test::UploadHeader("plot", false, /*create_map=*/true)));
    for (int m = 0; m < 5; ++m) ASSERT_TRUE(writer->Write(Chunk(m * 1000 + 1, 1000)));
    ASSERT_TRUE(Eventually([&] { return Pending() >= 4000; }));
    context->TryCancel();  // the client dies
    EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::CANCELLED);
  }
  ASSERT_TRUE(Eventually([&] { return Pending() == 0; })) << Pending();
  grpc::Status status;
  GetMap("plot", &status);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  // The same command again works, and a create of an existing map is refused up front.
  ASSERT_TRUE(Upload("plot", 3000, /*create=*/true).ok());
  const v1::Map map = GetMap("plot");
  EXPECT_EQ(map.tree_count(), 3000);
  EXPECT_EQ(map.version(), 2);
  status = Upload("plot", 10, /*create=*/true);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_EQ(GetMap("plot").tree_count(), 3000);
}

// Finding 3: exports are read page by page while the client reads, from one version.
TEST_F(StreamBoundsTest, SlowReaderGetsTheWholeVersionItStartedOn) {
  ASSERT_TRUE(Upload("big", 12000, /*create=*/true).ok());
  gated_.Close("big");  // the second page waits until the map has changed
  v1::ExportTreesRequest request;
  request.set_name("big");
  auto context = BoundsContext();
  auto reader = stub_->ExportTrees(context.get(), request);
  v1::ExportTreesResponse message;
  ASSERT_TRUE(reader->Read(&message));
  const int64_t version = message.map_version();
  std::vector<int64_t> ids;
  for (const v1::Tree& tree : message.trees()) ids.push_back(tree.id());
  // The map changes while the client dawdles: the export stays on its version.
  ASSERT_TRUE(Upload("big", 100, /*create=*/false, /*replace=*/true).ok());
  gated_.Open();
  while (reader->Read(&message)) {
    EXPECT_EQ(message.map_version(), version);
    EXPECT_LE(message.trees_size(), 500);
    for (const v1::Tree& tree : message.trees()) ids.push_back(tree.id());
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(ids.size(), 12000u);
  for (size_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], static_cast<int64_t>(i) + 1);
  EXPECT_EQ(GetMap("big").tree_count(), 100);
}

TEST_F(StreamBoundsTest, PruningTheExportedVersionAbortsTheExport) {
  ASSERT_TRUE(Upload("big", 3000, /*create=*/true).ok());
  gated_.Close("big");  // the second page waits until the version is pruned
  v1::ExportTreesRequest request;
  request.set_name("big");
  auto context = BoundsContext();
  auto reader = stub_->ExportTrees(context.get(), request);
  v1::ExportTreesResponse message;
  ASSERT_TRUE(reader->Read(&message));
  ASSERT_TRUE(Upload("big", 10, false, /*replace=*/true).ok());
  store_.PruneVersions("big", 1);
  gated_.Open();
  while (reader->Read(&message)) {
  }
  const grpc::Status status = reader->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("pruned"));
}

TEST_F(StreamBoundsTest, StreamsOverTheLimitsAreResourceExhausted) {
  ASSERT_TRUE(CreateMap("m").ok());
  struct Open {
    std::unique_ptr<grpc::ClientContext> context = BoundsContext();
    v1::UploadTreesResponse response;
    std::unique_ptr<grpc::ClientWriter<v1::UploadTreesRequest>> writer;
  };
  const auto open = [](Stub& stub) {
    auto call = std::make_unique<Open>();
    call->writer = stub.UploadTrees(call->context.get(), &call->response);
    return call;
  };
  auto first = open(*stub_);
  auto second = open(*stub_);
  ASSERT_TRUE(Eventually([&] { return service_.stream_limits().open() == 2; }));
  auto third = open(*stub_);  // a third stream of the same client
  grpc::Status status = third->writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("limit per client"));

  std::unique_ptr<Stub> other = NewStub();  // another client may open one more
  auto fourth = open(*other);
  ASSERT_TRUE(Eventually([&] { return service_.stream_limits().open() == 3; }));
  v1::ExportTreesRequest request;
  request.set_name("m");
  auto context = BoundsContext();
  auto reader = NewStub()->ExportTrees(context.get(), request);  // a third client: server full
  status = reader->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("--max-streams 3"));

  for (Open* call : {first.get(), second.get(), fourth.get()}) {
    ASSERT_TRUE(call->writer->Write(test::UploadHeader("m")));
    call->writer->WritesDone();
    EXPECT_TRUE(call->writer->Finish().ok());
  }
  ASSERT_TRUE(Eventually([&] { return service_.stream_limits().open() == 0; }));
  EXPECT_TRUE(Upload("m", 10).ok());  // places are given back
}

}  // namespace
}  // namespace forestmap::server
