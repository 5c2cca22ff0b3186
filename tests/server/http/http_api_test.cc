// The web page's JSON API (server/http/http_page.h) as the page's script reads it: a map's
// versions with the page's own names of their kinds, and the last relocalizations from the
// application layer's RecentAnswers, newest first, with a position only when localized.

#include <gtest/gtest.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server/app/recent_answers.h"
#include "server/http/http_page.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "tests/server/http_get.h"

namespace forestmap::server {
namespace {

using Json = nlohmann::json;

std::vector<storage::TreeRecord> RowTrees(int count) {
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) trees[i].x = 2.0 * i;
  return trees;
}

class HttpApiTest : public ::testing::Test {
 protected:
  HttpApiTest() {
    store_.CreateMap("plot", "", "");
    store_.WriteTrees("plot", RowTrees(4), storage::WriteMode::kAppend);
    store_.WriteTrees("plot", RowTrees(3), storage::WriteMode::kReplace);
    page_ = std::make_unique<HttpPage>(store_, answers_, "127.0.0.1:0");
  }
  Json GetJson(const std::string& path) {
    const std::string& address = page_->address();
    const test::HttpAnswer answer =
        test::HttpGet("127.0.0.1", std::stoi(address.substr(address.rfind(':') + 1)), path);
    EXPECT_EQ(answer.status, 200) << path << ": " << answer.body;
    return Json::parse(answer.body);
  }

  storage::SqliteMapStore store_{":memory:"};
  RecentAnswers answers_;
  std::unique_ptr<HttpPage> page_;
};

TEST_F(HttpApiTest, VersionsCarryTheirKindAndTreeCount) {
  const Json versions = GetJson("/api/maps/plot/versions");
  ASSERT_EQ(versions.size(), 3u);
  EXPECT_EQ(versions[0]["version"], 1);
  EXPECT_EQ(versions[0]["kind"], "CREATE");
  EXPECT_EQ(versions[0]["trees"], 0);
  EXPECT_EQ(versions[1]["kind"], "UPLOAD");
  EXPECT_EQ(versions[1]["trees"], 4);
  EXPECT_EQ(versions[2]["kind"], "REPLACE");
  EXPECT_EQ(versions[2]["trees"], 3);
  EXPECT_EQ(versions[2]["source"], "");
  EXPECT_TRUE(versions[2]["time_ms"].is_number_integer());
}

TEST_F(HttpApiTest, BoundaryIsTheMapsPolygonsOuterRingFirst) {
  EXPECT_EQ(GetJson("/api/maps/plot/boundary")["polygons"], Json::array());  // none yet
  storage::UploadPlan plan;
  storage::BoundaryPolygon polygon;
  polygon.outer = {{0, 0}, {10.5, 0}, {10.5, 10}};
  polygon.holes = {{{2, 1}, {3, 1}, {3, 2}}};
  plan.boundary = storage::Boundary{polygon};
  store_.BeginUpload("plot", plan)->Commit();
  const Json polygons = GetJson("/api/maps/plot/boundary")["polygons"];
  ASSERT_EQ(polygons.size(), 1u);
  ASSERT_EQ(polygons[0].size(), 2u);  // the outer ring, one hole
  EXPECT_EQ(polygons[0][0], Json::parse("[[0, 0], [10.5, 0], [10.5, 10]]"));
  EXPECT_EQ(polygons[0][1][2], Json::parse("[3, 2]"));
}

TEST_F(HttpApiTest, RelocalizationsNewestFirstWithAPositionOnlyWhenLocalized) {
  algorithms::RelocalizeResult localized;
  localized.status = algorithms::RelocalizeStatus::kLocalized;
  localized.inliers = 9;
  localized.map_from_sensor.translation() = Eigen::Vector3d(12.5, -3.25, 1.0);
  geo::GeodeticPose where;
  where.latitude_deg = 46.5;
  where.longitude_deg = 7.25;
  answers_.Add("plot", localized, where);
  algorithms::RelocalizeResult ambiguous;
  ambiguous.status = algorithms::RelocalizeStatus::kAmbiguous;
  ambiguous.inliers = 4;
  ambiguous.map_from_sensor.translation() = Eigen::Vector3d(99, 99, 0);  // not a pose: not shown
  answers_.Add("plot", ambiguous, std::nullopt);

  const Json answers = GetJson("/api/relocalizations");
  ASSERT_EQ(answers.size(), 2u);
  EXPECT_EQ(answers[0]["status"], "AMBIGUOUS");
  EXPECT_EQ(answers[0]["inliers"], 4);
  EXPECT_FALSE(answers[0].contains("x"));
  EXPECT_FALSE(answers[0].contains("lat"));
  EXPECT_EQ(answers[1]["map"], "plot");
  EXPECT_EQ(answers[1]["status"], "LOCALIZED");
  EXPECT_EQ(answers[1]["inliers"], 9);
  EXPECT_EQ(answers[1]["x"], 12.5);
  EXPECT_EQ(answers[1]["y"], -3.25);
  EXPECT_EQ(answers[1]["lat"], 46.5);
  EXPECT_EQ(answers[1]["lon"], 7.25);
  EXPECT_GE(answers[0]["time_ms"].get<int64_t>(), answers[1]["time_ms"].get<int64_t>());
}

}  // namespace
}  // namespace forestmap::server
