// The ForestMap service end to end: a real in-process gRPC server on 127.0.0.1 port 0 over an
// in-memory SQLite store, called through the generated stub.

#include "server/grpc/service.h"

#include <gmock/gmock.h>
#include <google/protobuf/util/message_differencer.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <limits>
#include <random>

#include "server/grpc/server.h"
#include "storage/sqlite/store.h"
#include "tests/server/grpc/validation_test_util.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using google::protobuf::util::MessageDifferencer;
using ::testing::HasSubstr;

using test::kNaN;
constexpr auto kCallDeadline = std::chrono::seconds(20);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> Context() { return test::CallContext(kCallDeadline); }

// `count` trees with explicit ids first_id.., random coordinates in [0, 200) m, and every
// combination of optional z / dbh / attributes.
std::vector<v1::Tree> RandomTrees(int count, int64_t first_id, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(0.0, 200.0);
  std::vector<v1::Tree> trees(count);
  for (int i = 0; i < count; ++i) {
    v1::Tree& tree = trees[i];
    tree.set_id(first_id + i);
    tree.set_x(coord(rng));
    tree.set_y(coord(rng));
    if (i % 2 == 0) tree.set_z(coord(rng) / 100.0);
    if (i % 3 == 0) tree.set_dbh(coord(rng) / 500.0);
    if (i % 5 == 0) (*tree.mutable_attributes())["species"] = i % 10 == 0 ? "pine" : "spruce";
  }
  return trees;
}

class ServiceTest : public ::testing::Test {
 protected:
  explicit ServiceTest(ServiceOptions options = {})
      : service_(store_, options),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}

  v1::Map CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    const grpc::Status status = stub_->CreateMap(Context().get(), request, &map);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return map;
  }

  v1::Map GetMap(const std::string& name) {
    v1::GetMapRequest request;
    request.set_name(name);
    v1::Map map;
    const grpc::Status status = stub_->GetMap(Context().get(), request, &map);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return map;
  }

  // Uploads `trees`: a header, then messages of `chunk` trees.
  grpc::Status Upload(const std::string& name, const std::vector<v1::Tree>& trees, size_t chunk,
                      bool replace = false, v1::UploadTreesResponse* response = nullptr) {
    v1::UploadTreesResponse ignored;
    auto context = Context();
    auto writer = stub_->UploadTrees(context.get(), response ? response : &ignored);
    v1::UploadTreesRequest header;
    header.mutable_header()->set_name(name);
    header.mutable_header()->set_replace(replace);
    bool open = writer->Write(header);
    for (size_t next = 0; open && next < trees.size();) {
      v1::UploadTreesRequest message;
      for (size_t end = std::min(trees.size(), next + chunk); next < end; ++next) {
        *message.mutable_chunk()->add_trees() = trees[next];
      }
      open = writer->Write(message);  // false: the server already answered
    }
    writer->WritesDone();
    return writer->Finish();
  }

  struct Export {
    grpc::Status status;
    std::vector<v1::Tree> trees;
    std::vector<int64_t> versions;  // one per message
  };
  Export ExportTrees(const std::string& name, const v1::Box2* box = nullptr) {
    v1::ExportTreesRequest request;
    request.set_name(name);
    if (box != nullptr) *request.mutable_box() = *box;
    auto context = Context();
    auto reader = stub_->ExportTrees(context.get(), request);
    Export out;
    v1::ExportTreesResponse message;
    while (reader->Read(&message)) {
      out.versions.push_back(message.map_version());
      out.trees.insert(out.trees.end(), message.trees().begin(), message.trees().end());
    }
    out.status = reader->Finish();
    return out;
  }

  // The server still answers after an error.
  void ExpectServing() {
    v1::ListMapsResponse response;
    const grpc::Status status = stub_->ListMaps(Context().get(), v1::ListMapsRequest(), &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }

  storage::SqliteMapStore store_{":memory:"};
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
};

void ExpectSameTrees(const std::vector<v1::Tree>& actual, const std::vector<v1::Tree>& expected) {
  ASSERT_EQ(actual.size(), expected.size());
  for (size_t i = 0; i < actual.size(); ++i) {
    // Uploaded trees are surveys: they come back confirmed.
    v1::Tree want = expected[i];
    if (want.status() == v1::TREE_STATUS_UNSPECIFIED) want.set_status(v1::TREE_STATUS_CONFIRMED);
    // Exact comparison of doubles: coordinates must come back bit-identical.
    EXPECT_TRUE(MessageDifferencer::Equals(actual[i], want)) << "tree " << i << ":\n"
                                                             << actual[i].DebugString() << "vs\n"
                                                             << want.DebugString();
  }
}

TEST_F(ServiceTest, CreateListGetDelete) {
  v1::CreateMapRequest request;
  request.set_name("plot-b");
  request.set_description("Boreal plot B");
  request.set_crs("EPSG:32612");
  v1::Map created;
  ASSERT_TRUE(stub_->CreateMap(Context().get(), request, &created).ok());
  EXPECT_EQ(created.name(), "plot-b");
  EXPECT_EQ(created.description(), "Boreal plot B");
  EXPECT_EQ(created.crs(), "EPSG:32612");
  EXPECT_EQ(created.version(), 1);
  EXPECT_EQ(created.tree_count(), 0);
  EXPECT_FALSE(created.has_extent());
  CreateMap("plot-a");

  v1::ListMapsResponse list;
  ASSERT_TRUE(stub_->ListMaps(Context().get(), v1::ListMapsRequest(), &list).ok());
  ASSERT_EQ(list.maps_size(), 2);
  EXPECT_EQ(list.maps(0).name(), "plot-a");  // sorted by name
  EXPECT_TRUE(MessageDifferencer::Equals(list.maps(1), created));
  EXPECT_TRUE(MessageDifferencer::Equals(GetMap("plot-b"), created));

  v1::DeleteMapRequest remove;
  remove.set_name("plot-b");
  v1::DeleteMapResponse removed;
  ASSERT_TRUE(stub_->DeleteMap(Context().get(), remove, &removed).ok());
  v1::GetMapRequest get;
  get.set_name("plot-b");
  v1::Map map;
  const grpc::Status gone = stub_->GetMap(Context().get(), get, &map);
  EXPECT_EQ(gone.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(gone.error_message(), HasSubstr("plot-b"));
}

TEST_F(ServiceTest, UploadInChunksThenExportReturnsExactlyTheUpload) {
  CreateMap("plot");
  const std::vector<v1::Tree> trees = RandomTrees(12345, 1, 42);
  v1::UploadTreesResponse response;
  ASSERT_TRUE(Upload("plot", trees, 1000, false, &response).ok());
  EXPECT_EQ(response.trees_received(), 12345);
  EXPECT_EQ(response.map().tree_count(), 12345);
  EXPECT_EQ(response.map().version(), 2);
  ASSERT_TRUE(response.map().has_extent());
  EXPECT_GE(response.map().extent().min_x(), 0.0);
  EXPECT_LT(response.map().extent().max_x(), 200.0);

  const Export exported = ExportTrees("plot");
  ASSERT_TRUE(exported.status.ok()) << exported.status.error_message();
  EXPECT_EQ(exported.versions.size(), 3u);  // 5,000 trees per message
  for (int64_t version : exported.versions) EXPECT_EQ(version, 2);
  ExpectSameTrees(exported.trees, trees);
}

TEST_F(ServiceTest, ExportWithBoxReturnsTheTreesInside) {
  CreateMap("plot");
  const std::vector<v1::Tree> trees = RandomTrees(3000, 100, 7);
  ASSERT_TRUE(Upload("plot", trees, 700).ok());
  v1::Box2 box;
  box.set_min_x(20);
  box.set_min_y(50);
  box.set_max_x(80.5);
  box.set_max_y(120);
  std::vector<v1::Tree> inside;
  for (const v1::Tree& tree : trees) {
    if (tree.x() >= box.min_x() && tree.x() <= box.max_x() && tree.y() >= box.min_y() &&
        tree.y() <= box.max_y()) {
      inside.push_back(tree);
    }
  }
  ASSERT_GT(inside.size(), 100u);
  const Export exported = ExportTrees("plot", &box);
  ASSERT_TRUE(exported.status.ok()) << exported.status.error_message();
  ExpectSameTrees(exported.trees, inside);
  for (int64_t version : exported.versions) EXPECT_EQ(version, 2);
}

TEST_F(ServiceTest, EmptyExportStillTellsTheVersion) {
  CreateMap("empty");
  const Export exported = ExportTrees("empty");
  ASSERT_TRUE(exported.status.ok());
  EXPECT_TRUE(exported.trees.empty());
  EXPECT_EQ(exported.versions, std::vector<int64_t>{1});
}

TEST_F(ServiceTest, AppendAssignsIdsAndBumpsTheVersion) {
  CreateMap("plot");
  ASSERT_TRUE(Upload("plot", RandomTrees(10, 50, 1), 4).ok());
  std::vector<v1::Tree> anonymous = RandomTrees(5, 0, 2);
  for (v1::Tree& tree : anonymous) tree.clear_id();
  v1::UploadTreesResponse response;
  ASSERT_TRUE(Upload("plot", anonymous, 5, false, &response).ok());
  EXPECT_EQ(response.map().version(), 3);
  EXPECT_EQ(response.map().tree_count(), 15);
  const Export exported = ExportTrees("plot");
  ASSERT_EQ(exported.trees.size(), 15u);
  for (int i = 0; i < 5; ++i) {
    const v1::Tree& tree = exported.trees[10 + i];
    EXPECT_GT(tree.id(), 59);  // above every existing id, in upload order
    EXPECT_EQ(tree.x(), anonymous[i].x());
  }
}

TEST_F(ServiceTest, ReplaceMakesTheMapExactlyTheUpload) {
  CreateMap("plot");
  ASSERT_TRUE(Upload("plot", RandomTrees(100, 1, 3), 30).ok());
  const std::vector<v1::Tree> replacement = RandomTrees(40, 1000, 4);
  v1::UploadTreesResponse response;
  ASSERT_TRUE(Upload("plot", replacement, 15, true, &response).ok());
  EXPECT_EQ(response.map().tree_count(), 40);
  EXPECT_EQ(response.map().version(), 3);
  ExpectSameTrees(ExportTrees("plot").trees, replacement);
}

TEST_F(ServiceTest, UnknownMapIsNotFoundEverywhere) {
  v1::GetMapRequest get;
  get.set_name("nowhere");
  v1::Map map;
  grpc::Status status = stub_->GetMap(Context().get(), get, &map);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("nowhere"));
  v1::DeleteMapRequest remove;
  remove.set_name("nowhere");
  v1::DeleteMapResponse removed;
  status = stub_->DeleteMap(Context().get(), remove, &removed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("nowhere"));
  status = Upload("nowhere", RandomTrees(10, 1, 5), 10);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("nowhere"));
  const Export exported = ExportTrees("nowhere");
  EXPECT_EQ(exported.status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(exported.status.error_message(), HasSubstr("nowhere"));
  ExpectServing();
}

TEST_F(ServiceTest, DuplicateMapIsAlreadyExists) {
  CreateMap("plot");
  v1::CreateMapRequest request;
  request.set_name("plot");
  v1::Map map;
  const grpc::Status status = stub_->CreateMap(Context().get(), request, &map);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_THAT(status.error_message(), HasSubstr("plot"));
  ExpectServing();
}

TEST_F(ServiceTest, InvalidNamesAreInvalidArgument) {
  for (const std::string& name :
       std::vector<std::string>{"", "two words", std::string(200, 'x'), "a/b"}) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    const grpc::Status status = stub_->CreateMap(Context().get(), request, &map);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << name;
    EXPECT_THAT(status.error_message(), HasSubstr("name")) << name;
  }
  ExpectServing();
}

TEST_F(ServiceTest, NonFiniteTreeFailsTheWholeUpload) {
  CreateMap("plot");
  ASSERT_TRUE(Upload("plot", RandomTrees(10, 1, 1), 10).ok());
  std::vector<v1::Tree> trees = RandomTrees(3000, 100, 2);
  trees[2345].set_y(kNaN);  // in the third message of 1,000
  const grpc::Status status = Upload("plot", trees, 1000);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("trees[2345].y is NaN"));
  const v1::Map map = GetMap("plot");
  EXPECT_EQ(map.version(), 2);  // unchanged: nothing of the failed upload was written
  EXPECT_EQ(map.tree_count(), 10);
}

TEST_F(ServiceTest, DuplicateIdsFailTheWholeUpload) {
  CreateMap("plot");
  std::vector<v1::Tree> trees = RandomTrees(2000, 1, 3);
  trees[1500].set_id(trees[20].id());  // across messages
  grpc::Status status = Upload("plot", trees, 500);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("trees[1500].id 21 duplicates trees[20].id"));
  EXPECT_EQ(GetMap("plot").tree_count(), 0);

  // An id already in the map, when appending, is refused by the store.
  ASSERT_TRUE(Upload("plot", RandomTrees(10, 1, 4), 10).ok());
  status = Upload("plot", RandomTrees(3, 10, 5), 10);  // ids 10..12; 10 is taken
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("id 10"));
  EXPECT_EQ(GetMap("plot").tree_count(), 10);
  EXPECT_EQ(GetMap("plot").version(), 2);
}

TEST_F(ServiceTest, UploadMustStartWithAHeader) {
  CreateMap("plot");
  v1::UploadTreesResponse response;
  auto context = Context();
  auto writer = stub_->UploadTrees(context.get(), &response);
  v1::UploadTreesRequest message;
  *message.mutable_chunk()->add_trees() = RandomTrees(1, 1, 1)[0];
  writer->Write(message);
  writer->WritesDone();
  grpc::Status status = writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("header is missing"));

  auto empty_context = Context();
  auto empty = stub_->UploadTrees(empty_context.get(), &response);
  empty->WritesDone();
  status = empty->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("header is missing"));
  EXPECT_EQ(GetMap("plot").version(), 1);
}

TEST_F(ServiceTest, UploadCannotSwitchMaps) {
  CreateMap("plot");
  CreateMap("other");
  v1::UploadTreesResponse response;
  auto context = Context();
  auto writer = stub_->UploadTrees(context.get(), &response);
  v1::UploadTreesRequest first;
  first.mutable_header()->set_name("plot");
  writer->Write(first);
  v1::UploadTreesRequest second;
  second.mutable_header()->set_name("other");
  writer->Write(second);
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("only the first message of an upload is a header"));
  EXPECT_EQ(GetMap("plot").version(), 1);
  EXPECT_EQ(GetMap("other").version(), 1);
}

TEST_F(ServiceTest, BadExportBoxIsInvalidArgument) {
  CreateMap("plot");
  v1::Box2 box;
  box.set_min_x(10);
  box.set_max_x(0);
  const Export exported = ExportTrees("plot", &box);
  EXPECT_EQ(exported.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(exported.status.error_message(), HasSubstr("box"));
  ExpectServing();
}

class SmallLimitsServiceTest : public ServiceTest {
 protected:
  static ServiceOptions SmallLimits() {
    ServiceOptions options;
    options.max_upload_trees = 100;
    options.export_chunk_trees = 7;
    return options;
  }
  SmallLimitsServiceTest() : ServiceTest(SmallLimits()) {}
};

TEST_F(SmallLimitsServiceTest, UploadOverTheLimitIsResourceExhausted) {
  CreateMap("plot");
  const grpc::Status status = Upload("plot", RandomTrees(150, 1, 1), 40);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(status.error_message(), HasSubstr("100 trees"));
  EXPECT_EQ(GetMap("plot").tree_count(), 0);
  ASSERT_TRUE(Upload("plot", RandomTrees(100, 1, 1), 40).ok());  // exactly the limit is fine
  const Export exported = ExportTrees("plot");
  EXPECT_EQ(exported.versions.size(), 15u);  // ceil(100 / 7) messages
  EXPECT_EQ(exported.trees.size(), 100u);
}

}  // namespace
}  // namespace forestmap::server
