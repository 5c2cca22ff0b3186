#include "client/lib/forestmap_client.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "tests/client/fake_forestmap_server.h"

namespace forestmap::client {
namespace {

using testing::FakeForestMapServer;

std::vector<MapTreeRow> MakeRows(int n, bool with_ids) {
  std::vector<MapTreeRow> rows;
  for (int i = 0; i < n; ++i) {
    MapTreeRow row;
    if (with_ids) row.id = 1000 + i;
    row.x = i * 0.5;
    row.y = -i * 0.25;
    if (i % 2) row.z = 100.0 + i;
    if (i % 3) row.dbh = 0.1 + i * 1e-5;
    if (i % 5 == 0) row.attributes["species"] = "pine";
    rows.push_back(row);
  }
  return rows;
}

TEST(ForestMapClientTest, ManagesMaps) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  const v1::Map created = client.CreateMap("plot-1", "a plot", "EPSG:2959");
  EXPECT_EQ(created.name(), "plot-1");
  EXPECT_EQ(created.crs(), "EPSG:2959");
  client.CreateMap("plot-2");
  const std::vector<v1::Map> maps = client.ListMaps();
  ASSERT_EQ(maps.size(), 2u);
  EXPECT_EQ(maps[1].name(), "plot-2");
  EXPECT_EQ(client.GetMap("plot-1").description(), "a plot");
  client.DeleteMap("plot-1");
  EXPECT_EQ(client.ListMaps().size(), 1u);
}

TEST(ForestMapClientTest, ServerErrorsBecomeRpcErrorsWithTheServersMessage) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  try {
    client.GetMap("nope");
    FAIL() << "expected RpcError";
  } catch (const RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::NOT_FOUND);
    EXPECT_STREQ(error.what(), "GetMap: NOT_FOUND: no map named 'nope'");
  }
  client.CreateMap("a");
  try {
    client.CreateMap("a");
    FAIL() << "expected RpcError";
  } catch (const RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::ALREADY_EXISTS);
  }
}

// The fields the server names in its error details (google.rpc.BadRequest) follow its message.
TEST(ForestMapClientTest, RpcErrorsShowTheBadFieldsOfTheErrorDetails) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  try {
    client.CreateMap("");
    FAIL() << "expected RpcError";
  } catch (const RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_STREQ(error.what(), "CreateMap: INVALID_ARGUMENT: name is empty (field: name)");
  }
}

TEST(ForestMapClientTest, UploadStreamsChunksOf5000AndReportsProgress) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  client.CreateMap("big");
  const std::vector<MapTreeRow> rows = MakeRows(12345, /*with_ids=*/false);
  std::vector<std::pair<int64_t, int64_t>> progress;
  const v1::UploadTreesResponse response =
      client.UploadTrees("big", rows, /*replace=*/true,
                         [&](int64_t sent, int64_t total) { progress.emplace_back(sent, total); });
  EXPECT_EQ(response.trees_received(), 12345);
  EXPECT_EQ(response.map().tree_count(), 12345);
  EXPECT_EQ(response.map().version(), 2);
  const auto& messages = server.service().upload_messages;
  ASSERT_EQ(messages.size(), 4u);  // the header, then the chunks
  ASSERT_TRUE(messages[0].has_header());
  EXPECT_EQ(messages[0].header().name(), "big");
  EXPECT_TRUE(messages[0].header().replace());
  EXPECT_FALSE(messages[0].header().request_id().empty());  // exactly-once
  EXPECT_EQ(messages[1].chunk().trees_size(), 5000);
  EXPECT_EQ(messages[2].chunk().trees_size(), 5000);
  EXPECT_EQ(messages[3].chunk().trees_size(), 2345);
  const std::vector<std::pair<int64_t, int64_t>> expected = {
      {5000, 12345}, {10000, 12345}, {12345, 12345}};
  EXPECT_EQ(progress, expected);

  // The server assigned ids 0.. in order; everything else comes back unchanged.
  const ExportedTrees exported = client.ExportTrees("big");
  EXPECT_EQ(exported.map_version, 2);
  ASSERT_EQ(exported.trees.size(), rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    MapTreeRow expected_row = rows[i];
    expected_row.id = static_cast<int64_t>(i);
    ASSERT_EQ(exported.trees[i], expected_row) << i;
  }
}

TEST(ForestMapClientTest, UploadExportRoundTripKeepsIdsAndAttributes) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  client.CreateMap("m");
  const std::vector<MapTreeRow> rows = MakeRows(2500, /*with_ids=*/true);
  client.UploadTrees("m", rows, /*replace=*/false);
  EXPECT_EQ(client.ExportTrees("m").trees, rows);
  // Only the trees inside the box.
  const ExportedTrees boxed = client.ExportTrees("m", Box2{0, -1, 2, 0});
  ASSERT_EQ(boxed.trees.size(), 5u);  // x = 0, 0.5, ..., 2
  EXPECT_EQ(boxed.trees.back().x, 2.0);
}

TEST(ForestMapClientTest, EmptyReplacingUploadSendsItsHeader) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  client.CreateMap("m");
  client.UploadTrees("m", MakeRows(10, true), false);
  const v1::UploadTreesResponse response = client.UploadTrees("m", {}, /*replace=*/true);
  ASSERT_EQ(server.service().upload_messages.size(), 1u);
  EXPECT_TRUE(server.service().upload_messages[0].header().replace());
  EXPECT_EQ(response.map().tree_count(), 0);
}

TEST(ForestMapClientTest, ListMapsFollowsThePages) {
  FakeForestMapServer server;  // pages of kListPage (2) maps
  ForestMapClient client(server.address());
  for (const char* name : {"e", "a", "d", "b", "c"}) client.CreateMap(name);
  std::vector<std::string> names;
  for (const v1::Map& map : client.ListMaps()) names.push_back(map.name());
  EXPECT_EQ(names, (std::vector<std::string>{"a", "b", "c", "d", "e"}));
}

TEST(ForestMapClientTest, RelocalizeSendsTreesPriorAndGravity) {
  FakeForestMapServer server;
  ForestMapClient client(server.address());
  client.CreateMap("m");
  std::vector<algorithms::DetectedTree> trees(12);
  for (size_t i = 0; i < trees.size(); ++i) trees[i].position = {1.0 * i, 2.0, 0.5};
  trees[0].dbh = 0.3;
  trees[0].axis = {0, 0, 1};
  trees[0].score = 0.9;
  const PriorPosition prior{5, 6, 15};
  const v1::RelocalizeResponse response =
      client.Relocalize("m", trees, prior, Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(response.status(), v1::RelocalizeResponse::STATUS_LOCALIZED);
  const v1::RelocalizeRequest& request = server.service().last_relocalize;
  ASSERT_EQ(request.trees_size(), 12);
  EXPECT_EQ(request.trees(3).position().x(), 3.0);
  EXPECT_EQ(request.trees(0).dbh(), 0.3);
  EXPECT_TRUE(request.trees(0).has_axis());
  EXPECT_EQ(request.trees(0).score(), 0.9);
  EXPECT_FALSE(request.trees(1).has_dbh());
  EXPECT_FALSE(request.trees(1).has_axis());
  EXPECT_FALSE(request.trees(1).has_score());
  ASSERT_TRUE(request.has_prior());
  EXPECT_EQ(request.prior().radius_m(), 15);
  EXPECT_EQ(request.prior().x(), 5);
  EXPECT_EQ(request.prior().y(), 6);
  ASSERT_TRUE(request.has_gravity());
  EXPECT_EQ(request.gravity().z(), -1);

  client.Relocalize("m", trees);
  EXPECT_FALSE(server.service().last_relocalize.has_prior());
  EXPECT_FALSE(server.service().last_relocalize.has_gravity());
}

TEST(ForestMapClientTest, UnreachableServerSaysSoAndNamesTheAddress) {
  ForestMapClient client("127.0.0.1:1");
  try {
    client.ListMaps();
    FAIL() << "expected RpcError";
  } catch (const RpcError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::UNAVAILABLE);
    const std::string message = error.what();
    EXPECT_EQ(message.rfind("cannot reach forestmapd at 127.0.0.1:1: ", 0), 0u) << message;
    EXPECT_NE(message.find("(is it running? use --server)"), std::string::npos) << message;
  }
}

TEST(ForestMapClientTest, InvalidOptionsAreRejected) {
  ClientOptions options;
  options.upload_chunk_trees = 0;
  EXPECT_THROW(ForestMapClient("127.0.0.1:1", options), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::client
