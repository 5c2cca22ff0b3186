// Robustness: findings that once crashed the server, cut uploads short, applied a
// retried write twice or let a fault look like a bug, each checked end to end through a real
// in-process gRPC server over a SQLite file.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

constexpr auto kRobustnessDeadline = std::chrono::seconds(20);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> RobustnessContext() {
  return test::CallContext(kRobustnessDeadline);
}

std::filesystem::path RobustnessTestDir() { return test::FreshTestDir("forestmap_robust_"); }

v1::Tree TreeAt(double x, double y) {
  v1::Tree tree;
  tree.set_x(x);
  tree.set_y(y);
  return tree;
}

class RobustnessTest : public ::testing::Test {
 protected:
  explicit RobustnessTest(ServiceOptions options = {})
      : dir_(RobustnessTestDir()),
        store_((dir_ / "maps.db").string()),
        gated_(store_),
        service_(gated_, options),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}
  ~RobustnessTest() override { std::filesystem::remove_all(dir_); }

  grpc::Status CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    return stub_->CreateMap(RobustnessContext().get(), request, &map);
  }

  // Uploads `trees` in one chunk after the header.
  grpc::Status Upload(const std::string& name, const std::vector<v1::Tree>& trees,
                      v1::UploadTreesResponse* response = nullptr,
                      const std::string& request_id = "", bool replace = false) {
    v1::UploadTreesResponse ignored;
    auto context = RobustnessContext();
    auto writer = stub_->UploadTrees(context.get(), response ? response : &ignored);
    v1::UploadTreesRequest header = test::UploadHeader(name, replace);
    header.mutable_header()->set_request_id(request_id);
    v1::UploadTreesRequest message;
    for (const v1::Tree& tree : trees) *message.mutable_chunk()->add_trees() = tree;
    if (writer->Write(header)) writer->Write(message);
    writer->WritesDone();
    return writer->Finish();
  }

  grpc::Status Relocalize(const std::string& name) {
    v1::RelocalizeRequest request;
    request.set_name(name);
    for (auto [x, y] : {std::pair{0.0, 0.0}, {3.0, 0.0}, {0.0, 4.0}}) {
      v1::DetectedTree* tree = request.add_trees();
      tree->mutable_position()->set_x(x);
      tree->mutable_position()->set_y(y);
    }
    v1::RelocalizeResponse response;
    return stub_->Relocalize(RobustnessContext().get(), request, &response);
  }

  void ExpectServing() {
    v1::ListMapsResponse response;
    const grpc::Status status =
        stub_->ListMaps(RobustnessContext().get(), v1::ListMapsRequest(), &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }

  std::filesystem::path dir_;
  storage::SqliteMapStore store_;
  GatedStore gated_;  // what the service uses: can slow merges down
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
  request.set_name("shared");
  request.set_source("drone1");
  v1::ObservationFrame* frame = request.add_frames();
  frame->mutable_map_from_sensor()->mutable_translation()->set_x(1e45);
  for (int i = 0; i < 3; ++i) frame->add_trees()->mutable_position()->set_x(2.0 * i);
  v1::ObserveResponse response;
  const grpc::Status status = stub_->Observe(RobustnessContext().get(), request, &response);
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
  auto context = RobustnessContext();
  auto writer = stub_->UploadTrees(context.get(), &response);
  ASSERT_TRUE(writer->Write(test::UploadHeader("plot")));
  for (int m = 0; m < 5; ++m) {
    v1::UploadTreesRequest message;
    for (int i = 0; i < 1000; ++i) {
      v1::Tree tree = TreeAt(m * 1000 + i, i);
      if (m == 3 && i == 7)
        (*tree.mutable_attributes())["species"] =
            "\xe9pic\xe9"
            "a";
      *message.mutable_chunk()->add_trees() = tree;
    }
    if (!writer->Write(message)) break;  // the server already answered
  }
  writer->WritesDone();
  const grpc::Status status = writer->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("upload message 4 (after 3000 trees)"));
  EXPECT_THAT(status.error_message(), HasSubstr("nothing was written"));
  EXPECT_EQ(store_.GetMap("plot").tree_count, 0);
  ExpectServing();
}

// Three frames seeing the same 6 trees from poses 1 m apart (map frame = sensor frame + x).
v1::ObserveRequest ObserveFrames(const std::string& request_id) {
  v1::ObserveRequest request;
  request.set_name("shared");
  request.set_source("drone1");
  request.set_request_id(request_id);
  for (int f = 0; f < 3; ++f) {
    v1::ObservationFrame* frame = request.add_frames();
    frame->set_frame_id(f);
    frame->mutable_map_from_sensor()->mutable_translation()->set_x(f);
    for (int t = 0; t < 6; ++t) {
      v1::DetectedTree* tree = frame->add_trees();
      tree->mutable_position()->set_x(5.0 * t - f);
      tree->mutable_position()->set_y(3.0 * (t % 2));
      tree->set_dbh(0.3);
    }
  }
  return request;
}

int64_t ObservationRows(storage::MapStore& store, const std::string& name) {
  int64_t rows = 0;
  for (const storage::VersionRecord& v : store.ListVersions(name, 0)) {
    rows += v.observations_added - v.observations_removed;
  }
  return rows;
}

// Finding 4: a retried Observe added its frames again (1,676 duplicate observations a retry).
TEST_F(RobustnessTest, RepeatedRequestIdsAreAppliedOnceAndAnsweredAlike) {
  ASSERT_TRUE(CreateMap("shared").ok());
  v1::ObserveResponse first, second;
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-1"), &first).ok());
  const int64_t rows = ObservationRows(store_, "shared");
  EXPECT_GE(rows, 12);  // 3 frames x 6 trees, less what the merge ignores
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-1"), &second).ok());
  EXPECT_EQ(ObservationRows(store_, "shared"), rows);  // not applied again
  EXPECT_EQ(second.map_version(), first.map_version());
  EXPECT_EQ(second.frames_size(), 3);
  EXPECT_EQ(second.frames(1).trees_associated(), first.frames(1).trees_associated());
  EXPECT_EQ(store_.GetMap("shared").version, first.map_version());
  // A new id is a new write.
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-2"), &second).ok());
  EXPECT_EQ(ObservationRows(store_, "shared"), 2 * rows);

  ASSERT_TRUE(CreateMap("plot").ok());
  const std::vector<v1::Tree> trees = {TreeAt(0, 0), TreeAt(3, 0), TreeAt(0, 4)};
  v1::UploadTreesResponse up1, up2;
  ASSERT_TRUE(Upload("plot", trees, &up1, "up-1").ok());
  ASSERT_TRUE(Upload("plot", trees, &up2, "up-1").ok());  // would be duplicate ids if applied
  EXPECT_EQ(up2.map().version(), up1.map().version());
  EXPECT_EQ(up2.trees_received(), 3);
  EXPECT_EQ(store_.GetMap("plot").tree_count, 3);

  v1::CreateMapRequest create;
  create.set_name("again");
  create.set_request_id("create-1");
  v1::Map made1, made2;
  ASSERT_TRUE(stub_->CreateMap(RobustnessContext().get(), create, &made1).ok());
  const grpc::Status retried = stub_->CreateMap(RobustnessContext().get(), create, &made2);
  EXPECT_TRUE(retried.ok()) << retried.error_message();  // not ALREADY_EXISTS
  EXPECT_EQ(made2.created_unix_ms(), made1.created_unix_ms());

  // An id belongs to one call.
  const grpc::Status reused = Upload("plot", trees, nullptr, "obs-1");
  EXPECT_EQ(reused.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(reused.error_message(), HasSubstr("already used for a Observe call"));
  const grpc::Status bad_id = Upload("plot", trees, nullptr, "has space");
  EXPECT_EQ(bad_id.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_id.error_message(), HasSubstr("request_id"));
}

// A request id reused for another map or other content was answered with the first request's
// answer, and the second write silently skipped.
TEST_F(RobustnessTest, ARequestIdReusedForAnotherRequestIsRefusedNeverAnswered) {
  ASSERT_TRUE(CreateMap("plot").ok());
  ASSERT_TRUE(CreateMap("other").ok());
  const std::vector<v1::Tree> trees = {TreeAt(0, 0), TreeAt(3, 0), TreeAt(0, 4)};
  v1::UploadTreesResponse first, retried;
  ASSERT_TRUE(Upload("plot", trees, &first, "up-1").ok());
  const auto refused = [](const grpc::Status& status) {
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr("request_id"));
    EXPECT_THAT(status.error_message(), HasSubstr("different request"));
  };
  refused(Upload("other", trees, nullptr, "up-1"));  // another map
  EXPECT_EQ(store_.GetMap("other").tree_count, 0);
  refused(Upload("plot", {TreeAt(9, 9)}, nullptr, "up-1"));  // other trees
  EXPECT_EQ(store_.GetMap("plot").tree_count, 3);
  ASSERT_TRUE(Upload("plot", trees, &retried, "up-1").ok());  // the same request: its answer
  EXPECT_EQ(retried.map().version(), first.map().version());
  EXPECT_EQ(store_.GetMap("plot").tree_count, 3);

  ASSERT_TRUE(CreateMap("shared").ok());
  v1::ObserveResponse observed;
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-1"), &observed).ok());
  v1::ObserveRequest elsewhere = ObserveFrames("obs-1");
  elsewhere.set_name("other");
  refused(stub_->Observe(RobustnessContext().get(), elsewhere, &observed));
  EXPECT_EQ(ObservationRows(store_, "other"), 0);
  v1::ObserveRequest moved = ObserveFrames("obs-1");
  moved.mutable_frames(0)->mutable_trees(0)->set_dbh(0.5);
  refused(stub_->Observe(RobustnessContext().get(), moved, &observed));

  v1::CreateMapRequest create;
  create.set_name("made");
  create.set_request_id("create-1");
  v1::Map made;
  ASSERT_TRUE(stub_->CreateMap(RobustnessContext().get(), create, &made).ok());
  create.set_name("made-too");
  refused(stub_->CreateMap(RobustnessContext().get(), create, &made));
  EXPECT_THROW(store_.GetMap("made-too"), storage::StorageError);
}

// Finding 4: an Observe whose deadline passed (the CLI's 30 s under load) was committed anyway.
TEST_F(RobustnessTest, WriteWhoseDeadlinePassedBeforeTheCommitIsNotCommitted) {
  ASSERT_TRUE(CreateMap("shared").ok());
  const int64_t version = store_.GetMap("shared").version;
  gated_.merge_delay = std::chrono::milliseconds(1500);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(400));
  v1::ObserveResponse response;
  const grpc::Status late = stub_->Observe(&context, ObserveFrames("obs-late"), &response);
  EXPECT_EQ(late.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));  // the server's merge ends
  EXPECT_EQ(store_.GetMap("shared").version, version);
  EXPECT_EQ(ObservationRows(store_, "shared"), 0);
  // The retry with the same id (and time enough) is applied, once.
  gated_.merge_delay = std::chrono::milliseconds(0);
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-late"), &response).ok());
  const int64_t rows = ObservationRows(store_, "shared");
  EXPECT_GE(rows, 12);
  EXPECT_EQ(store_.GetMap("shared").version, version + 1);
  ASSERT_TRUE(stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-late"), &response).ok());
  EXPECT_EQ(ObservationRows(store_, "shared"), rows);
}

// Finding 5: history was never pruned (eight replace uploads left a 1.05 GB database).
TEST_F(RobustnessTest, PruneVersionsKeepsTheNewestVersions) {
  ASSERT_TRUE(CreateMap("plot").ok());
  for (int upload = 0; upload < 4; ++upload) {
    std::vector<v1::Tree> trees;
    for (int i = 0; i < 50; ++i) trees.push_back(TreeAt(100.0 * upload + 2 * i, i));
    ASSERT_TRUE(Upload("plot", trees, nullptr, "", /*replace=*/true).ok());
  }
  v1::PruneVersionsRequest request;
  request.set_name("plot");
  request.set_keep(2);
  v1::PruneVersionsResponse response;
  grpc::Status status = stub_->PruneVersions(RobustnessContext().get(), request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.versions_removed(), 3);     // 1, 2, 3 of 1..5
  EXPECT_EQ(response.tree_rows_removed(), 100);  // the trees of versions 2 and 3
  EXPECT_EQ(response.map().version(), 5);
  EXPECT_EQ(store_.ListVersions("plot", 0).size(), 2u);
  EXPECT_EQ(store_.GetMap("plot").tree_count, 50);
  request.set_keep(0);
  status = stub_->PruneVersions(RobustnessContext().get(), request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("keep is 0"));
}

class RetentionTest : public RobustnessTest {
 protected:
  RetentionTest() : RobustnessTest(Retaining()) {}
  static ServiceOptions Retaining() {
    ServiceOptions options;
    options.keep_versions = 3;
    return options;
  }
};

TEST_F(RetentionTest, KeepVersionsPolicyPrunesAfterEveryWrite) {
  ASSERT_TRUE(CreateMap("shared").ok());
  for (int i = 0; i < 6; ++i) {
    v1::ObserveResponse response;
    ASSERT_TRUE(stub_
                    ->Observe(RobustnessContext().get(), ObserveFrames("obs-" + std::to_string(i)),
                              &response)
                    .ok());
    EXPECT_LE(store_.ListVersions("shared", 0).size(), 3u) << "after observe " << i;
  }
  EXPECT_EQ(store_.GetMap("shared").version, 7);
  EXPECT_EQ(store_.ListVersions("shared", 0).front().version, 5);
}

// The upload stream commits apart from the unary writes; it applies the same retention.
TEST_F(RetentionTest, UploadsArePrunedAfterTheirCommitToo) {
  ASSERT_TRUE(CreateMap("plot").ok());
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(Upload("plot", {TreeAt(10.0 * i, 0)}).ok());
    EXPECT_LE(store_.ListVersions("plot", 0).size(), 3u) << "after upload " << i;
  }
  EXPECT_EQ(store_.GetMap("plot").version, 6);
  EXPECT_EQ(store_.GetMap("plot").tree_count, 5);
  EXPECT_EQ(store_.ListVersions("plot", 0).front().version, 4);
}

// A retention that fails after a committed write: the write stands and is answered OK (a retry
// would find it applied), and the failure is in the log with its cause, from either path.
TEST_F(RetentionTest, AFailedRetentionIsLoggedAndTheWriteStands) {
  ASSERT_TRUE(CreateMap("shared").ok());
  gated_.before_prune = [] {
    throw storage::StorageError(storage::StorageError::Code::kFull, "disk full (injected)");
  };
  ::testing::internal::CaptureStderr();
  v1::ObserveResponse observed;
  const grpc::Status observe =
      stub_->Observe(RobustnessContext().get(), ObserveFrames("obs-1"), &observed);
  const grpc::Status upload = Upload("shared", {TreeAt(50, 50)});
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_TRUE(observe.ok()) << observe.error_message();
  EXPECT_TRUE(upload.ok()) << upload.error_message();
  EXPECT_EQ(store_.GetMap("shared").version, 3);  // both writes are there
  const std::string line =
      "retention of map \"shared\" failed (the write stands): disk full (injected)";
  const size_t first = log.find(line);
  ASSERT_NE(first, std::string::npos) << log;
  EXPECT_NE(log.find(line, first + 1), std::string::npos) << "one line per write: " << log;
}

}  // namespace
}  // namespace forestmap::server
