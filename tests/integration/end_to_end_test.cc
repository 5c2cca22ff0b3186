// End to end through the real wire: a forestmapd service on a loopback port over SQLite, driven
// by the client library as the `forestmap` command drives it. Real maps go up and come back
// identical; real Wild_V02 frames relocalize against the uploaded Wild_V01 map.
#include <filesystem>

#include <gtest/gtest.h>

#include "algorithms/reloc_evaluation.h"
#include "client/forestmap_client.h"
#include "client/proto_convert.h"
#include "client/tree_csv.h"
#include "server/server.h"
#include "server/service.h"
#include "storage/sqlite_map_store.h"

namespace forestmap {
namespace {

const std::string kData = FORESTMAP_SHARED_DATA;

class EndToEnd : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kData + "/sequences/Wild_V01/map.csv")) {
      GTEST_SKIP() << "real data missing under " << kData;
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
    if (response.status() == v1::RelocalizeResponse::LOCALIZED) {
      result.status = algorithms::RelocalizeStatus::kLocalized;
      result.map_from_sensor = client::FromProto(response.map_from_sensor());
      EXPECT_GT(response.confidence(), 0.0);
      EXPECT_EQ(response.matches_size(), response.inliers());
    } else {
      result.status = response.status() == v1::RelocalizeResponse::AMBIGUOUS
                          ? algorithms::RelocalizeStatus::kAmbiguous
                          : algorithms::RelocalizeStatus::kNotFound;
    }
    evaluator.Add(evaluator.Answerable(frames[i].trees, truth), truth, result,
                  response.server_time_ms());
  }
  const algorithms::RelocSummary s = evaluator.Summary();
  std::cout << "Wild_V02 vs Wild_V01 through forestmapd: " << s.correct << "/" << s.answerable
            << " correct (recall " << s.recall << ", strict " << s.strict_recall << "), "
            << s.wrong << " wrong, median error " << s.error_xy_p50 << " m, server p50 "
            << s.time_p50 << " ms\n";
  EXPECT_GE(s.frames, 100);
  EXPECT_GE(s.recall, 0.97);
  EXPECT_EQ(s.wrong, 0);
}

}  // namespace
}  // namespace forestmap
