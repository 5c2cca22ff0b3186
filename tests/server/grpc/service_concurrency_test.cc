// The ForestMap service under concurrency, cancellation and hostile input, plus Relocalize:
// a real in-process gRPC server on 127.0.0.1 port 0 over an in-memory SQLite store whose
// snapshot reads can be held at a gate.

#include <gmock/gmock.h>
#include <google/protobuf/unknown_field_set.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <future>
#include <limits>
#include <random>
#include <set>
#include <thread>

#include "server/grpc/convert.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

constexpr auto kConcurrencyDeadline = std::chrono::seconds(20);  // turns a hang into a failure
constexpr double kPositionTolerance = 0.05;                      // m, noise-free query
constexpr double kYawTolerance = 0.005;                          // rad

std::unique_ptr<grpc::ClientContext> ConcurrencyContext() {
  return test::CallContext(kConcurrencyDeadline);
}

// A forest of `count` trees with ids 1..count, x, y uniform in [0, 100) m, z = 0, dbh known.
std::vector<storage::TreeRecord> RandomForest(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(0.0, 100.0);
  std::uniform_real_distribution<double> dbh(0.1, 0.5);
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].id = i + 1;
    trees[i].x = coord(rng);
    trees[i].y = coord(rng);
    trees[i].z = 0.0;
    trees[i].dbh = dbh(rng);
  }
  return trees;
}

// The map trees within `range` of (x, y), seen from a sensor at `map_from_sensor`.
v1::RelocalizeRequest ViewOf(const std::string& map, const std::vector<storage::TreeRecord>& trees,
                             const algorithms::Pose3& map_from_sensor, double range) {
  v1::RelocalizeRequest request;
  request.set_name(map);
  const algorithms::Pose3 sensor_from_map = map_from_sensor.inverse();
  const Eigen::Vector3d center = map_from_sensor.translation();
  for (const storage::TreeRecord& tree : trees) {
    if (std::hypot(tree.x - center.x(), tree.y - center.y()) > range) continue;
    const Eigen::Vector3d p = sensor_from_map * Eigen::Vector3d(tree.x, tree.y, *tree.z);
    v1::DetectedTree* detected = request.add_trees();
    detected->mutable_position()->set_x(p.x());
    detected->mutable_position()->set_y(p.y());
    detected->mutable_position()->set_z(p.z());
    detected->set_dbh(*tree.dbh);
  }
  return request;
}

class ServiceConcurrencyTest : public ::testing::Test {
 protected:
  explicit ServiceConcurrencyTest(const ServerOptions& server_options = {})
      : service_(store_, ServiceOptions()),
        runner_("127.0.0.1:0", service_, server_options),
        channel_(grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials())),
        stub_(v1::ForestMap::NewStub(channel_)) {}

  // Creates a map holding `trees` (nothing written when empty).
  void AddMap(const std::string& name, const std::vector<storage::TreeRecord>& trees) {
    store_.CreateMap(name, "", "");
    if (!trees.empty()) store_.WriteTrees(name, trees, storage::WriteMode::kAppend);
  }

  grpc::Status Relocalize(const v1::RelocalizeRequest& request, v1::RelocalizeResponse* response) {
    return stub_->Relocalize(ConcurrencyContext().get(), request, response);
  }

  void ExpectServing() {
    v1::ListMapsResponse response;
    const grpc::Status status =
        stub_->ListMaps(ConcurrencyContext().get(), v1::ListMapsRequest(), &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
  }

  storage::SqliteMapStore sqlite_{":memory:"};
  GatedStore store_{sqlite_};
  ForestMapService service_;
  ServerRunner runner_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
};

// Sends raw bytes as the request of `method` and returns the status and the raw response.
std::pair<grpc::Status, std::string> RawCall(const std::shared_ptr<grpc::Channel>& channel,
                                             const std::string& method,
                                             const std::string& payload) {
  grpc::GenericStub stub(channel);
  grpc::Slice slice(payload);
  const grpc::ByteBuffer request(&slice, 1);
  grpc::ByteBuffer response;
  std::promise<grpc::Status> done;
  auto context = ConcurrencyContext();
  stub.UnaryCall(context.get(), method, grpc::StubOptions(), &request, &response,
                 [&done](grpc::Status status) { done.set_value(std::move(status)); });
  const grpc::Status status = done.get_future().get();
  std::string bytes;
  if (status.ok()) {
    grpc::Slice single;
    if (response.DumpToSingleSlice(&single).ok()) {
      bytes.assign(reinterpret_cast<const char*>(single.begin()), single.size());
    }
  }
  return {status, bytes};
}

// grpc.health.v1.HealthCheckResponse.status (field 1) from the raw bytes; -1 if absent.
int64_t HealthStatus(const std::string& bytes) {
  google::protobuf::UnknownFieldSet fields;
  if (!fields.ParseFromString(bytes)) return -1;
  for (int i = 0; i < fields.field_count(); ++i) {
    if (fields.field(i).number() == 1) return static_cast<int64_t>(fields.field(i).varint());
  }
  return -1;
}

TEST_F(ServiceConcurrencyTest, RelocalizeAnswersWithTheMapVersionItUsed) {
  const std::vector<storage::TreeRecord> forest = RandomForest(500, 1);
  AddMap("plot", forest);
  const algorithms::Pose3 truth = algorithms::PoseFromXyzYaw(50, 50, 1.5, 0.7);
  const v1::RelocalizeRequest request = ViewOf("plot", forest, truth, 15.0);
  ASSERT_GE(request.trees_size(), 10);
  v1::RelocalizeResponse response;
  const grpc::Status status = Relocalize(request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.map_version(), store_.GetMap("plot").version);
  EXPECT_GT(response.server_time_ms(), 0.0);
  // A noise-free view of ~35 trees of a random forest has one clear answer: the true pose.
  ASSERT_EQ(response.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << response.detail();
  const algorithms::Pose3 found = FromProto(response.map_from_sensor());
  EXPECT_LT((found.translation() - truth.translation()).head<2>().norm(), kPositionTolerance);
  EXPECT_LT(std::abs(algorithms::WrapAngle(algorithms::YawOf(found.linear()) -
                                           algorithms::YawOf(truth.linear()))),
            kYawTolerance);
  EXPECT_GE(response.inliers(), request.trees_size() * 9 / 10);
  std::set<int64_t> ids;
  for (const storage::TreeRecord& tree : forest) ids.insert(*tree.id);
  for (const v1::TreeMatch& match : response.matches()) {
    EXPECT_TRUE(ids.count(match.map_tree_id())) << match.map_tree_id();
    EXPECT_LT(match.query_index(), request.trees_size());
  }
}

TEST_F(ServiceConcurrencyTest, IndexIsRebuiltAfterAnUpload) {
  const std::vector<storage::TreeRecord> forest = RandomForest(300, 2);
  AddMap("plot", forest);
  const v1::RelocalizeRequest request =
      ViewOf("plot", forest, algorithms::PoseFromXyzYaw(40, 60, 1.5, -1.0), 15.0);
  v1::RelocalizeResponse before;
  ASSERT_TRUE(Relocalize(request, &before).ok());
  ASSERT_TRUE(Relocalize(request, &before).ok());
  EXPECT_EQ(store_.reads("plot"), 1);  // the second call used the cached index

  v1::UploadTreesResponse uploaded;
  auto context = ConcurrencyContext();
  auto writer = stub_->UploadTrees(context.get(), &uploaded);
  v1::UploadTreesRequest header;
  header.mutable_header()->set_name("plot");
  ASSERT_TRUE(writer->Write(header));
  v1::UploadTreesRequest message;
  v1::Tree* tree = message.mutable_chunk()->add_trees();
  tree->set_x(150);
  tree->set_y(150);
  ASSERT_TRUE(writer->Write(message));
  writer->WritesDone();
  ASSERT_TRUE(writer->Finish().ok());

  v1::RelocalizeResponse after;
  ASSERT_TRUE(Relocalize(request, &after).ok());
  EXPECT_EQ(after.map_version(), before.map_version() + 1);
  EXPECT_EQ(after.map_version(), uploaded.map().version());
  EXPECT_EQ(store_.reads("plot"), 2);
  EXPECT_EQ(service_.index_cache().stats().builds, 2);
}

TEST_F(ServiceConcurrencyTest, ConcurrentRelocalizationsShareOneIndex) {
  const std::vector<storage::TreeRecord> forest = RandomForest(400, 3);
  AddMap("plot", forest);
  const int64_t version = store_.GetMap("plot").version;
  constexpr int kThreads = 8;
  constexpr int kCallsPerThread = 4;
  std::vector<std::future<int>> workers;
  for (int t = 0; t < kThreads; ++t) {
    workers.push_back(std::async(std::launch::async, [&, t] {
      int ok = 0;
      for (int i = 0; i < kCallsPerThread; ++i) {
        const v1::RelocalizeRequest request = ViewOf(
            "plot", forest, algorithms::PoseFromXyzYaw(20 + 7 * t, 30 + 5 * i, 1.5, 0.3 * t), 15);
        v1::RelocalizeResponse response;
        if (Relocalize(request, &response).ok() && response.map_version() == version) ++ok;
      }
      return ok;
    }));
  }
  for (auto& worker : workers) EXPECT_EQ(worker.get(), kCallsPerThread);
  EXPECT_EQ(store_.reads("plot"), 1);
  EXPECT_EQ(service_.index_cache().stats().builds, 1);
}

TEST_F(ServiceConcurrencyTest, AnIndexBuildDoesNotBlockOtherCalls) {
  const std::vector<storage::TreeRecord> slow_forest = RandomForest(200, 4);
  const std::vector<storage::TreeRecord> fast_forest = RandomForest(200, 5);
  AddMap("slow", slow_forest);
  AddMap("fast", fast_forest);
  const algorithms::Pose3 pose = algorithms::PoseFromXyzYaw(50, 50, 1.5, 2.0);
  store_.Close("slow");
  auto first = std::async(std::launch::async, [&] {
    v1::RelocalizeResponse response;
    return Relocalize(ViewOf("slow", slow_forest, pose, 20), &response);
  });
  ASSERT_TRUE(Eventually([&] { return store_.reads("slow") == 1; }));
  auto second = std::async(std::launch::async, [&] {
    v1::RelocalizeResponse response;
    return Relocalize(ViewOf("slow", slow_forest, pose, 20), &response);
  });
  ASSERT_TRUE(Eventually([&] { return service_.index_cache().stats().waits == 1; }));

  // Both calls for "slow" are in the server, one building and one waiting for that build.
  ExpectServing();
  v1::RelocalizeResponse fast;
  EXPECT_TRUE(Relocalize(ViewOf("fast", fast_forest, pose, 20), &fast).ok());
  store_.Open();
  EXPECT_TRUE(first.get().ok());
  EXPECT_TRUE(second.get().ok());
  EXPECT_EQ(store_.reads("slow"), 1);  // one build for both
}

TEST_F(ServiceConcurrencyTest, RelocalizeRejectsBadQueries) {
  const std::vector<storage::TreeRecord> forest = RandomForest(100, 6);
  AddMap("plot", forest);
  AddMap("empty", {});
  const v1::RelocalizeRequest good =
      ViewOf("plot", forest, algorithms::PoseFromXyzYaw(50, 50, 0, 0), 30);
  ASSERT_GE(good.trees_size(), 10);
  v1::RelocalizeResponse response;

  v1::RelocalizeRequest two = good;
  two.mutable_trees()->DeleteSubrange(2, two.trees_size() - 2);
  two.set_client_stamp_ns(1234567890123456789);
  grpc::Status status = Relocalize(two, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();  // too few trees: an answer, not an error
  EXPECT_EQ(response.status(), v1::RelocalizeResponse::STATUS_NOT_FOUND);
  EXPECT_EQ(response.reason(), v1::RelocalizeResponse::REASON_TOO_FEW_TREES);
  EXPECT_EQ(response.client_stamp_ns(), 1234567890123456789);

  v1::RelocalizeRequest huge = good;
  while (huge.trees_size() < 100000) *huge.add_trees() = good.trees(0);
  status = Relocalize(huge, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(status.error_message(), "trees: 100000 trees exceed the limit of 20000 per query");

  v1::RelocalizeRequest nan = good;
  nan.mutable_trees(1)->mutable_position()->set_x(std::numeric_limits<double>::quiet_NaN());
  status = Relocalize(nan, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("trees[1].position.x is NaN"));

  v1::RelocalizeRequest unknown = good;
  unknown.set_name("nowhere");
  status = Relocalize(unknown, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("nowhere"));

  v1::RelocalizeRequest empty = good;
  empty.set_name("empty");
  status = Relocalize(empty, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(status.error_message(), HasSubstr("\"empty\" has no confirmed trees"));

  EXPECT_TRUE(Relocalize(good, &response).ok());  // still serving
}

TEST_F(ServiceConcurrencyTest, CancelledUploadChangesNothing) {
  AddMap("plot", RandomForest(10, 7));
  const storage::MapInfo before = store_.GetMap("plot");
  const int uploads_begun = store_.uploads_begun();

  grpc::ClientContext context;
  v1::UploadTreesResponse response;
  auto writer = stub_->UploadTrees(&context, &response);
  v1::UploadTreesRequest header;
  header.mutable_header()->set_name("plot");
  ASSERT_TRUE(writer->Write(header));
  // The server has taken the first message once it began the upload (the map exists).
  ASSERT_TRUE(Eventually([&] { return store_.uploads_begun() > uploads_begun; }));
  v1::UploadTreesRequest message;
  for (int i = 0; i < 1000; ++i) {
    v1::Tree* tree = message.mutable_chunk()->add_trees();
    tree->set_x(i);
    tree->set_y(i);
  }
  writer->Write(message);
  context.TryCancel();
  EXPECT_EQ(writer->Finish().error_code(), grpc::StatusCode::CANCELLED);

  ExpectServing();
  const storage::MapInfo after = store_.GetMap("plot");
  EXPECT_EQ(after.version, before.version);
  EXPECT_EQ(after.tree_count, 10);
}

TEST_F(ServiceConcurrencyTest, GarbageRequestBytesAreRejected) {
  const std::string garbage("\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\x01\x02", 12);
  for (const char* method :
       {"/forestmap.v1.ForestMap/CreateMap", "/forestmap.v1.ForestMap/Relocalize"}) {
    const auto [status, bytes] = RawCall(channel_, method, garbage);
    EXPECT_FALSE(status.ok()) << method;
    ExpectServing();
  }
  EXPECT_TRUE(store_.ListMaps().empty());
}

TEST_F(ServiceConcurrencyTest, HealthCheckAnswersServing) {
  constexpr int64_t kServing = 1;  // grpc.health.v1.HealthCheckResponse.SERVING
  const auto [overall, overall_bytes] = RawCall(channel_, "/grpc.health.v1.Health/Check", "");
  ASSERT_TRUE(overall.ok()) << overall.error_message();
  EXPECT_EQ(HealthStatus(overall_bytes), kServing);

  const std::string name = v1::ForestMap::service_full_name();
  const std::string request = std::string("\x0a", 1) + static_cast<char>(name.size()) + name;
  const auto [service, service_bytes] = RawCall(channel_, "/grpc.health.v1.Health/Check", request);
  ASSERT_TRUE(service.ok()) << service.error_message();
  EXPECT_EQ(HealthStatus(service_bytes), kServing);
}

class SmallMessageLimitTest : public ServiceConcurrencyTest {
 protected:
  static ServerOptions OneMebibyte() {
    ServerOptions options;
    options.max_receive_message_bytes = 1 << 20;
    return options;
  }
  SmallMessageLimitTest() : ServiceConcurrencyTest(OneMebibyte()) {}
};

TEST_F(SmallMessageLimitTest, MessageOverTheLimitIsResourceExhausted) {
  v1::CreateMapRequest request;
  request.set_name("big");
  request.set_description(std::string(2 << 20, 'd'));
  v1::Map map;
  const grpc::Status status = stub_->CreateMap(ConcurrencyContext().get(), request, &map);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  ExpectServing();
  EXPECT_TRUE(store_.ListMaps().empty());
}

}  // namespace
}  // namespace forestmap::server
