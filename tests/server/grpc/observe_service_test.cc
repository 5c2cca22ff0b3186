// Shared maps through the real service: Observe (with and without poses, stale bases, bad
// requests), history, restore, remove-source, export of old versions, and concurrent drones.
// A synthetic forest with known trees and sensor poses is the truth.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <thread>

#include "proto/geometry_convert.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;
constexpr auto kObserveDeadline = std::chrono::seconds(60);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> ObserveContext() {
  return test::CallContext(kObserveDeadline);
}

// 500 trees at least 2.5 m apart in a 200 x 60 m strip; 100 frames every 2 m along it, each
// seeing the trees within 25 m (2 cm position noise, 1 cm DBH noise), sensor 1.5 m up, yawing.
struct Forest {
  std::vector<Eigen::Vector2d> trees;
  std::vector<double> dbh;
  std::vector<algorithms::Pose3> map_from_sensor;
  std::vector<std::vector<v1::DetectedTree>> detections;  // per frame, sensor frame
};

Forest MakeForest(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(0, 200), y(0, 60), d(0.15, 0.6);
  std::normal_distribution<double> noise(0, 0.02), dbh_noise(0, 0.01);
  Forest forest;
  while (forest.trees.size() < 500) {
    const Eigen::Vector2d p(x(rng), y(rng));
    bool free = true;
    for (const Eigen::Vector2d& q : forest.trees) free = free && (p - q).norm() >= 2.5;
    if (!free) continue;
    forest.trees.push_back(p);
    forest.dbh.push_back(d(rng));
  }
  for (int i = 0; i < 100; ++i) {
    const algorithms::Pose3 pose = algorithms::PoseFromXyzYaw(2.0 * i, 30 + 3 * std::sin(i / 7.0),
                                                              1.5, 0.3 * std::sin(i / 5.0));
    forest.map_from_sensor.push_back(pose);
    std::vector<v1::DetectedTree> seen;
    for (size_t t = 0; t < forest.trees.size(); ++t) {
      const Eigen::Vector3d ground(forest.trees[t].x(), forest.trees[t].y(), 0.0);
      if ((ground.head<2>() - pose.translation().head<2>()).norm() > 25) continue;
      const Eigen::Vector3d in_sensor = pose.inverse() * ground;
      v1::DetectedTree tree;
      *tree.mutable_position() = ToProto(
          Eigen::Vector3d(in_sensor.x() + noise(rng), in_sensor.y() + noise(rng), in_sensor.z()));
      tree.set_dbh(forest.dbh[t] + dbh_noise(rng));
      tree.set_score(0.8);
      seen.push_back(tree);
    }
    forest.detections.push_back(seen);
  }
  return forest;
}

const Forest& TheForest() {
  static const Forest forest = MakeForest(11);
  return forest;
}

// Frames [first, last) as one request.
v1::ObserveRequest Request(const std::string& map, const std::string& source, int first, int last,
                           bool with_poses = true) {
  const Forest& forest = TheForest();
  v1::ObserveRequest request;
  request.set_name(map);
  request.set_source(source);
  for (int i = first; i < last; ++i) {
    v1::ObservationFrame* frame = request.add_frames();
    frame->set_frame_id(i);
    for (const v1::DetectedTree& tree : forest.detections[i]) *frame->add_trees() = tree;
    if (with_poses) *frame->mutable_map_from_sensor() = ToProto(forest.map_from_sensor[i]);
  }
  return request;
}

class ObserveServiceTest : public ::testing::Test {
 protected:
  ObserveServiceTest()
      : dir_(std::filesystem::temp_directory_path() /
             ("forestmap_observe_" + std::to_string(getpid()) + "_" +
              ::testing::UnitTest::GetInstance()->current_test_info()->name())),
        store_(Prepare(dir_)),
        service_(store_, ServiceOptions{}),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}
  ~ObserveServiceTest() override { std::filesystem::remove_all(dir_); }

  static std::string Prepare(const std::filesystem::path& dir) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return (dir / "maps.db").string();
  }

  void CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    ASSERT_TRUE(stub_->CreateMap(ObserveContext().get(), request, &map).ok());
  }

  grpc::Status Observe(const v1::ObserveRequest& request, v1::ObserveResponse* response) {
    return stub_->Observe(ObserveContext().get(), request, response);
  }

  v1::ObserveResponse ObserveOk(const v1::ObserveRequest& request) {
    v1::ObserveResponse response;
    const grpc::Status status = Observe(request, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return response;
  }

  // Observes frames [first, last) in requests of `batch` frames.
  void ObserveRange(const std::string& map, const std::string& source, int first, int last,
                    int batch) {
    for (int begin = first; begin < last; begin += batch) {
      ObserveOk(Request(map, source, begin, std::min(last, begin + batch)));
    }
  }

  std::vector<v1::Tree> Export(const std::string& map, int64_t version = 0) {
    v1::ExportTreesRequest request;
    request.set_name(map);
    request.set_version(version);
    auto context = ObserveContext();
    auto reader = stub_->ExportTrees(context.get(), request);
    std::vector<v1::Tree> trees;
    v1::ExportTreesResponse message;
    while (reader->Read(&message)) {
      trees.insert(trees.end(), message.trees().begin(), message.trees().end());
    }
    const grpc::Status status = reader->Finish();
    EXPECT_TRUE(status.ok()) << status.error_message();
    return trees;
  }

  std::vector<v1::Tree> Confirmed(const std::string& map) {
    std::vector<v1::Tree> confirmed;
    for (const v1::Tree& tree : Export(map)) {
      if (tree.status() == v1::TREE_STATUS_CONFIRMED) confirmed.push_back(tree);
    }
    return confirmed;
  }

  std::filesystem::path dir_;
  storage::SqliteMapStore store_;
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
};

// Largest distance from a tree of `a` to the nearest tree of `b` (and the other way round).
double MaxMismatch(const std::vector<v1::Tree>& a, const std::vector<v1::Tree>& b) {
  double worst = 0;
  for (const auto* pair : {&a, &b}) {
    const auto& from = *pair;
    const auto& to = pair == &a ? b : a;
    for (const v1::Tree& p : from) {
      double best = std::numeric_limits<double>::infinity();
      for (const v1::Tree& q : to) best = std::min(best, std::hypot(p.x() - q.x(), p.y() - q.y()));
      worst = std::max(worst, best);
    }
  }
  return worst;
}

TEST_F(ObserveServiceTest, FramesWithPosesBuildAMapOfTheTrueTrees) {
  CreateMap("shared");
  int64_t detections = 0, merged = 0;
  for (int begin = 0; begin < 100; begin += 20) {
    const v1::ObserveResponse response = ObserveOk(Request("shared", "drone-1", begin, begin + 20));
    EXPECT_EQ(response.map_version(), 2 + begin / 20);  // one version per request
    ASSERT_EQ(response.frames_size(), 20);
    for (const v1::FrameResult& frame : response.frames()) {
      EXPECT_EQ(frame.status(), v1::FrameResult::STATUS_MERGED) << frame.detail();
      EXPECT_FALSE(frame.relocalized());
      merged += frame.trees_associated() + frame.trees_added() + frame.trees_ignored();
    }
  }
  for (const auto& frame : TheForest().detections) detections += static_cast<int64_t>(frame.size());
  EXPECT_EQ(merged, detections);
  const std::vector<v1::Tree> confirmed = Confirmed("shared");
  EXPECT_GT(confirmed.size(), 300u);
  const Forest& forest = TheForest();
  for (const v1::Tree& tree : confirmed) {  // every confirmed tree is a true tree, to 5 cm
    double best = 1e9;
    size_t nearest = 0;
    for (size_t t = 0; t < forest.trees.size(); ++t) {
      const double d = std::hypot(tree.x() - forest.trees[t].x(), tree.y() - forest.trees[t].y());
      if (d < best) best = d, nearest = t;
    }
    EXPECT_LT(best, 0.05) << "tree " << tree.id();
    EXPECT_NEAR(tree.dbh(), forest.dbh[nearest], 0.02);
    EXPECT_GE(tree.observations(), 3);
    EXPECT_GT(tree.position_sigma_m(), 0);
  }
}

// A surveyed map of x, y and DBH only (no stem heights): drone observations merge into it. The
// survey's prior rows have no sensor height (it used to reach the database as NULL and fail).
TEST_F(ObserveServiceTest, FramesMergeIntoASurveyWithoutHeights) {
  CreateMap("survey");
  v1::UploadTreesRequest header;
  header.mutable_header()->set_name("survey");
  v1::UploadTreesRequest upload;
  const Forest& forest = TheForest();
  for (size_t t = 0; t < forest.trees.size(); ++t) {
    v1::Tree* tree = upload.mutable_chunk()->add_trees();
    tree->set_x(forest.trees[t].x());
    tree->set_y(forest.trees[t].y());
    tree->set_dbh(forest.dbh[t]);  // no z
  }
  v1::UploadTreesResponse uploaded;
  auto context = ObserveContext();
  auto writer = stub_->UploadTrees(context.get(), &uploaded);
  ASSERT_TRUE(writer->Write(header));
  ASSERT_TRUE(writer->Write(upload));
  ASSERT_TRUE(writer->WritesDone());
  const grpc::Status status = writer->Finish();
  ASSERT_TRUE(status.ok()) << status.error_message();

  const v1::ObserveResponse response = ObserveOk(Request("survey", "drone-1", 0, 20));
  ASSERT_EQ(response.frames_size(), 20);
  for (const v1::FrameResult& frame : response.frames()) {
    EXPECT_EQ(frame.status(), v1::FrameResult::STATUS_MERGED) << frame.detail();
  }
  EXPECT_GT(response.map_version(), uploaded.map().version());
}

TEST_F(ObserveServiceTest, FramesWithoutPosesAreRelocalizedFirst) {
  CreateMap("surveyed");
  // Without confirmed trees nothing can be relocalized: frames are skipped, with the reason.
  v1::ObserveResponse response = ObserveOk(Request("surveyed", "drone-1", 10, 12, false));
  EXPECT_EQ(response.map_version(), 1);
  EXPECT_EQ(response.frames(0).status(), v1::FrameResult::STATUS_SKIPPED);
  EXPECT_THAT(response.frames(0).detail(), HasSubstr("no confirmed trees"));

  ObserveRange("surveyed", "drone-0", 0, 100, 25);  // builds confirmed trees (version 5)
  v1::ObserveRequest request = Request("surveyed", "drone-1", 40, 50, false);
  request.mutable_frames(9)->mutable_trees()->DeleteSubrange(2, request.frames(9).trees_size() - 2);
  request.add_frames()->set_frame_id(1000);  // no trees at all
  response = ObserveOk(request);
  EXPECT_EQ(response.map_version(), 6);
  ASSERT_EQ(response.frames_size(), 11);
  for (int i = 0; i < 9; ++i) {
    const v1::FrameResult& frame = response.frames(i);
    ASSERT_EQ(frame.status(), v1::FrameResult::STATUS_MERGED) << frame.detail();
    EXPECT_TRUE(frame.relocalized());
    const Eigen::Vector3d found = FromProto(frame.map_from_sensor()).translation();
    const Eigen::Vector3d truth = TheForest().map_from_sensor[40 + i].translation();
    EXPECT_LT((found - truth).head<2>().norm(), 0.1) << "frame " << frame.frame_id();
    EXPECT_GT(frame.trees_associated(), 10);
  }
  EXPECT_EQ(response.frames(9).status(), v1::FrameResult::STATUS_SKIPPED);
  EXPECT_THAT(response.frames(9).detail(), HasSubstr("fewer than 3 trees"));
  EXPECT_EQ(response.frames(10).status(), v1::FrameResult::STATUS_SKIPPED);
  EXPECT_THAT(response.frames(10).detail(), HasSubstr("neither trees nor a pose"));
}

TEST_F(ObserveServiceTest, StaleBaseVersionIsAbortedOrMergedByPolicy) {
  CreateMap("m");
  ObserveOk(Request("m", "drone-1", 0, 10));  // version 2
  v1::ObserveRequest request = Request("m", "drone-2", 10, 20);
  request.set_base_version(1);
  request.set_conflict_policy(v1::CONFLICT_POLICY_REJECT_IF_STALE);
  v1::ObserveResponse response;
  grpc::Status status = Observe(request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(status.error_message(), HasSubstr("not at the base version 1"));
  request.set_base_version(2);
  EXPECT_EQ(ObserveOk(request).map_version(), 3);
  request.set_base_version(2);
  request.set_conflict_policy(v1::CONFLICT_POLICY_MERGE);
  EXPECT_EQ(ObserveOk(request).map_version(), 4);  // stale, merged anyway
}

TEST_F(ObserveServiceTest, BadRequestsAreRejectedWithTheField) {
  CreateMap("m");
  const auto expect = [&](const v1::ObserveRequest& request, grpc::StatusCode code,
                          const std::string& fragment) {
    v1::ObserveResponse response;
    const grpc::Status status = Observe(request, &response);
    EXPECT_EQ(status.error_code(), code) << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr(fragment));
  };
  expect(Request("nope", "d", 0, 1), grpc::StatusCode::NOT_FOUND, "nope");
  expect(Request("bad name", "d", 0, 1), grpc::StatusCode::INVALID_ARGUMENT, "name \"bad name\"");
  expect(Request("m", "d", 0, 0), grpc::StatusCode::INVALID_ARGUMENT, "at least one frame");
  expect(Request("m", "survey", 0, 1), grpc::StatusCode::INVALID_ARGUMENT, "reserved");
  expect(Request("m", "", 0, 1), grpc::StatusCode::INVALID_ARGUMENT, "source is empty");
  v1::ObserveRequest nan = Request("m", "d", 0, 2);
  nan.mutable_frames(1)->mutable_trees(1)->mutable_position()->set_x(
      std::numeric_limits<double>::quiet_NaN());
  expect(nan, grpc::StatusCode::INVALID_ARGUMENT, "frames[1].trees[1].position.x is NaN");
  v1::ObserveRequest bad_pose = Request("m", "d", 0, 1);
  bad_pose.mutable_frames(0)->mutable_map_from_sensor()->mutable_rotation()->set_w(3);
  expect(bad_pose, grpc::StatusCode::INVALID_ARGUMENT, "frames[0].map_from_sensor.rotation");
  v1::ObserveRequest twice = Request("m", "d", 0, 2);
  twice.mutable_frames(1)->set_frame_id(0);
  expect(twice, grpc::StatusCode::INVALID_ARGUMENT, "duplicates frames[0].frame_id");
  expect(Request("m", "d", 0, 100), grpc::StatusCode::OK, "");
  v1::ObserveRequest many = Request("m", "d", 0, 1);
  for (int i = 1; i <= 200; ++i)
    *many.add_frames() = many.frames(0), many.mutable_frames(i)->set_frame_id(i);
  expect(many, grpc::StatusCode::RESOURCE_EXHAUSTED, "201 frames exceed the limit of 200");
  EXPECT_EQ(store_.GetMap("m").version, 2);  // only the valid request wrote
}

TEST_F(ObserveServiceTest, HistoryRestoreAndRemoveSource) {
  CreateMap("only-a");
  ObserveRange("only-a", "drone-a", 0, 60, 20);
  CreateMap("both");
  ObserveRange("both", "drone-a", 0, 60, 20);    // versions 2..4
  ObserveRange("both", "drone-b", 40, 100, 20);  // versions 5..7
  const std::vector<v1::Tree> version4 = Export("both", 4);

  v1::RemoveSourceRequest remove;
  remove.set_name("both");
  remove.set_source("drone-b");
  v1::RemoveSourceResponse removed;
  ASSERT_TRUE(stub_->RemoveSource(ObserveContext().get(), remove, &removed).ok());
  EXPECT_EQ(removed.map().version(), 8);
  EXPECT_GT(removed.trees_removed(), 50);  // trees only drone-b saw
  EXPECT_GT(removed.trees_updated(), 50);  // trees both saw
  // Trees are a pure function of their observations: without drone-b's, "both" is "only-a".
  const std::vector<v1::Tree> a = Export("only-a"), b = Export("both");
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a[i].x(), b[i].x(), 1e-9);
    EXPECT_NEAR(a[i].y(), b[i].y(), 1e-9);
    EXPECT_EQ(a[i].status(), b[i].status());
    EXPECT_EQ(a[i].observations(), b[i].observations());
  }
  grpc::Status status = stub_->RemoveSource(ObserveContext().get(), remove, &removed);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(status.error_message(), HasSubstr("no observations of source \"drone-b\""));

  v1::RestoreVersionRequest restore;
  restore.set_name("both");
  restore.set_version(7);
  v1::RestoreVersionResponse restored;
  ASSERT_TRUE(stub_->RestoreVersion(ObserveContext().get(), restore, &restored).ok());
  EXPECT_EQ(restored.map().version(), 9);
  EXPECT_EQ(Export("both").size(), Export("both", 7).size());
  EXPECT_EQ(Export("both", 4).size(), version4.size());
  restore.set_version(99);
  status = stub_->RestoreVersion(ObserveContext().get(), restore, &restored);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND);

  v1::ListVersionsRequest list;
  list.set_name("both");
  v1::ListVersionsResponse history;
  ASSERT_TRUE(stub_->ListVersions(ObserveContext().get(), list, &history).ok());
  ASSERT_EQ(history.versions_size(), 9);
  EXPECT_EQ(history.versions(0).kind(), v1::MapVersion::KIND_CREATE);
  EXPECT_EQ(history.versions(4).kind(), v1::MapVersion::KIND_OBSERVE);
  EXPECT_EQ(history.versions(4).source(), "drone-b");
  EXPECT_EQ(history.versions(7).kind(), v1::MapVersion::KIND_REMOVE_SOURCE);
  EXPECT_EQ(history.versions(8).kind(), v1::MapVersion::KIND_RESTORE);
  EXPECT_EQ(history.versions(8).restored_from(), 7);
}

// Four drones upload the four quarters of a sequence at the same time, 5 frames a request: no
// request fails and the trees equal those of a sequential upload in 25-frame requests, exactly
// (the map is a function of the set of observations, not of their order or batches).
TEST_F(ObserveServiceTest, ConcurrentDronesEqualTheSequentialUpload) {
  CreateMap("sequential");
  for (int q = 0; q < 4; ++q)
    ObserveRange("sequential", "drone-" + std::to_string(q), q * 25, q * 25 + 25, 25);
  CreateMap("concurrent");
  std::atomic<int> failures{0};
  std::vector<std::thread> drones;
  for (int q = 0; q < 4; ++q) {
    drones.emplace_back([&, q] {
      auto stub = v1::ForestMap::NewStub(
          grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()));
      for (int begin = q * 25; begin < q * 25 + 25; begin += 5) {
        v1::ObserveResponse response;
        const grpc::Status status = stub->Observe(
            ObserveContext().get(),
            Request("concurrent", "drone-" + std::to_string(q), begin, begin + 5), &response);
        if (!status.ok()) ++failures;
      }
    });
  }
  for (std::thread& drone : drones) drone.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(store_.GetMap("concurrent").version, 21);  // 20 merges, none lost
  const std::vector<v1::Tree> sequential = Confirmed("sequential");
  const std::vector<v1::Tree> concurrent = Confirmed("concurrent");
  EXPECT_EQ(concurrent.size(), sequential.size());
  EXPECT_EQ(MaxMismatch(sequential, concurrent), 0.0);
  EXPECT_EQ(Export("concurrent").size(), Export("sequential").size());  // candidates too
}

}  // namespace
}  // namespace forestmap::server
