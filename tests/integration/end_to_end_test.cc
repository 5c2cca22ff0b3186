// End to end through the real wire: a forestmapd service on a loopback port over SQLite, driven
// by the client library as the `forestmap` command drives it. Real maps go up and come back
// identical; real Wild_V02 frames relocalize against the uploaded Wild_V01 map.
#include <gtest/gtest.h>

#include <filesystem>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "client/lib/proto_convert.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/shared_data.h"

namespace forestmap {
namespace {

const std::string kData = FORESTMAP_SHARED_DATA;

class EndToEnd : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kData + "/sequences/Wild_V01/map.csv")) {
      FORESTMAP_SKIP_WITHOUT_DATA() << "real data missing under " << kData;
    }
    store_ = std::make_unique<storage::SqliteMapStore>(":memory:");
    service_ = std::make_unique<server::ForestMapService>(*store_, server::ServiceOptions{});
    runner_ = std::make_unique<server::ServerRunner>("127.0.0.1:0", *service_);
    client_ = std::make_unique<client::ForestMapClient>(runner_->address());
  }
  std::unique_ptr<storage::SqliteMapStore> store_;
  std::unique_ptr<server::ForestMapService> service_;
  std::unique_ptr<server::ServerRunner> runner_;
  std::unique_ptr<client::ForestMapClient> client_;
};

TEST_F(EndToEnd, EveryRealStemMapUploadsAndExportsIdentically) {
  int maps = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kData + "/stemmaps")) {
    const std::string file = entry.path().filename().string();
    if (file == "INDEX.csv" || entry.path().extension() != ".csv") continue;
    const std::vector<client::MapTreeRow> rows = client::ReadMapTreesCsv(entry.path().string());
    const std::string name = entry.path().stem().string();
    client_->CreateMap(name, "round trip", "");
    client_->UploadTrees(name, rows, /*replace=*/false, {});
    const client::ExportedTrees exported = client_->ExportTrees(name, std::nullopt);
    ASSERT_EQ(exported.trees.size(), rows.size()) << file;
    // Trees come back by id; the files list them by id too, but compare without relying on it.
    std::map<int64_t, client::MapTreeRow> by_id;
    for (const auto& row : exported.trees) by_id[*row.id] = row;
    for (const auto& row : rows) {
      ASSERT_TRUE(row.id.has_value()) << file;
      EXPECT_EQ(by_id.at(*row.id), row) << file;
    }
    ++maps;
  }
  EXPECT_EQ(maps, 22);
}

TEST_F(EndToEnd, SecondVisitFramesRelocalizeThroughTheServer) {
  const std::string seq = kData + "/sequences/";
  const auto map_rows = client::ReadMapTreesCsv(seq + "Wild_V01/map.csv");
  client_->CreateMap("venman", "Wild_V01 traversal map", "");
  client_->UploadTrees("venman", map_rows, false, {});

  algorithms::RelocEvaluator evaluator(client::ToMapTrees(map_rows));
  // map_V01_from_map_V02 (../shared/data/README.md).
  const algorithms::Pose3 v01_from_v02 =
      algorithms::PoseFromXyzYaw(0.051, 0.102, -0.039, -0.014 * M_PI / 180.0);
  const auto poses = client::ReadPosesCsv(seq + "Wild_V02/poses.csv");
  const auto frames = client::ReadFramesCsv(seq + "Wild_V02/trees.csv");
  for (size_t i = 0; i < frames.size(); i += 10) {  // 138 frames across the whole traversal
    const algorithms::Pose3 truth = v01_from_v02 * poses.at(frames[i].frame);
    const v1::RelocalizeResponse response =
        client_->Relocalize("venman", frames[i].trees, std::nullopt, std::nullopt);
    algorithms::RelocalizeResult result;
    if (response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED) {
      result.status = algorithms::RelocalizeStatus::kLocalized;
      result.map_from_sensor = client::FromProto(response.map_from_sensor());
      EXPECT_GT(response.confidence(), 0.0);
      EXPECT_EQ(response.matches_size(), response.inliers());
    } else {
      result.status = response.status() == v1::RelocalizeResponse::STATUS_AMBIGUOUS
                          ? algorithms::RelocalizeStatus::kAmbiguous
                          : algorithms::RelocalizeStatus::kNotFound;
    }
    evaluator.Add(evaluator.Answerable(frames[i].trees, truth), truth, result,
                  response.server_time_ms());
  }
  const algorithms::RelocSummary s = evaluator.Summary();
  std::cout << "Wild_V02 vs Wild_V01 through forestmapd: " << s.correct << "/" << s.answerable
            << " correct (recall " << s.recall << ", strict " << s.strict_recall << "), " << s.wrong
            << " wrong, median error " << s.error_xy_p50 << " m, server p50 " << s.time_p50
            << " ms\n";
  EXPECT_GE(s.frames, 100);
  EXPECT_GE(s.recall, 0.97);
  EXPECT_EQ(s.wrong, 0);
}

// A tracking session through the wire: 300 consecutive Wild_V02 frames against the V01 map, the
// first frames empty (the session starts lost), answers in order with the frame ids.
TEST_F(EndToEnd, ATrackingSessionFollowsTheSecondVisit) {
  const std::string seq = kData + "/sequences/";
  client_->CreateMap("venman", "", "");
  client_->UploadTrees("venman", client::ReadMapTreesCsv(seq + "Wild_V01/map.csv"), false, {});
  const algorithms::Pose3 v01_from_v02 =
      algorithms::PoseFromXyzYaw(0.051, 0.102, -0.039, -0.014 * M_PI / 180.0);
  const auto poses = client::ReadPosesCsv(seq + "Wild_V02/poses.csv");
  const auto frames = client::ReadFramesCsv(seq + "Wild_V02/trees.csv");

  client::TrackSession session = client_->Track("venman");
  for (int64_t id = -2; id < 0; ++id) {  // nothing seen yet
    const v1::TrackResponse response = session.Step({id, {}, {}, {}});
    EXPECT_EQ(response.frame_id(), id);
    EXPECT_EQ(response.state(), v1::TrackResponse::STATE_LOST);
    EXPECT_EQ(response.frames_lost(), id + 3);
  }
  int tracking = 0, correct = 0;
  const size_t n = 300;
  for (size_t i = 0; i < n; ++i) {
    const v1::TrackResponse response =
        session.Step({frames[i].frame, frames[i].trees, std::nullopt, std::nullopt});
    ASSERT_EQ(response.frame_id(), frames[i].frame);
    EXPECT_GT(response.result().map_version(), 0);
    if (i == 0) {
      EXPECT_EQ(response.state(), v1::TrackResponse::STATE_RECOVERED);
    }
    tracking += response.state() == v1::TrackResponse::STATE_TRACKING;
    if (response.result().status() != v1::RelocalizeResponse::STATUS_LOCALIZED) continue;
    const algorithms::PoseError error =
        algorithms::ComparePoses(client::FromProto(response.result().map_from_sensor()),
                                 v01_from_v02 * poses.at(frames[i].frame));
    EXPECT_LE(error.xy, 1.0) << "frame " << frames[i].frame;  // never wrong
    correct += error.xy <= 0.5 && error.yaw <= 5;
  }
  session.Finish();
  EXPECT_GE(correct, static_cast<int>(n) - 1);
  EXPECT_GE(tracking, static_cast<int>(0.9 * n));
}

TEST_F(EndToEnd, ABadFrameEndsTheSessionWithItsNumberAndTheServerKeepsServing) {
  client_->CreateMap("plot", "", "");
  client_->UploadTrees("plot", client::ReadMapTreesCsv(kData + "/sequences/Wild_V01/map.csv"),
                       false, {});
  const std::vector<algorithms::DetectedTree> trees(3, algorithms::DetectedTree{});
  auto expect_error = [&](const std::string& map, std::vector<algorithms::DetectedTree> frame,
                          grpc::StatusCode code, const std::string& message) {
    client::TrackSession session = client_->Track(map);
    session.Step({1, trees, {}, {}});
    try {
      session.Step({2, frame, {}, {}});
      ADD_FAILURE() << "no error for " << message;
    } catch (const client::RpcError& error) {
      EXPECT_EQ(error.code(), code);
      EXPECT_NE(std::string(error.what()).find(message), std::string::npos) << error.what();
    }
  };
  std::vector<algorithms::DetectedTree> nan = trees;
  nan[1].position.x() = std::nan("");
  expect_error("plot", nan, grpc::StatusCode::INVALID_ARGUMENT,
               "frame 2: frame.trees[1].position.x is NaN");
  expect_error("plot", std::vector<algorithms::DetectedTree>(20001),
               grpc::StatusCode::RESOURCE_EXHAUSTED,
               "frame 2: frame.trees: 20001 trees exceed the limit");
  try {
    client_->Track("no-such-map").Step({7, trees, {}, {}});
    ADD_FAILURE() << "no error for an unknown map";
  } catch (const client::RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::NOT_FOUND) << error.what();
    EXPECT_NE(std::string(error.what()).find("frame 7: "), std::string::npos) << error.what();
  }
  // The server still answers.
  client::TrackSession session = client_->Track("plot");
  EXPECT_EQ(session.Step({3, trees, {}, {}}).state(), v1::TrackResponse::STATE_LOST);
  session.Finish();
}

}  // namespace
}  // namespace forestmap
