#include "client/cli/cli_format.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace forestmap::client {
namespace {

std::string PriorError(const std::string& text) {
  try {
    ParsePrior(text);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

TEST(CliFormatTest, ParsesPriorPositionInMetres) {
  const PriorPosition prior = ParsePrior("12.5, -3,20");
  EXPECT_EQ(prior.x, 12.5);
  EXPECT_EQ(prior.y, -3);
  EXPECT_EQ(prior.radius_m, 20);
  // The four numbers of older versions: X,Y,YAW_DEG,RADIUS_M, the heading unused.
  const PriorPosition old = ParsePrior("12.5,-3,90,20");
  EXPECT_EQ(old.x, 12.5);
  EXPECT_EQ(old.y, -3);
  EXPECT_EQ(old.radius_m, 20);
}

TEST(CliFormatTest, RejectsMalformedPriors) {
  const std::string expected = "expected X,Y,RADIUS_M (3 numbers, m) or X,Y,YAW_DEG,RADIUS_M, got ";
  EXPECT_EQ(PriorError("1,2"), expected + "'1,2'");
  EXPECT_EQ(PriorError("1,2,3,4,5"), expected + "'1,2,3,4,5'");
  EXPECT_EQ(PriorError(""), "'' is not a number; " + expected + "''");
  EXPECT_EQ(PriorError("1,,3,4"), "'' is not a number; " + expected + "'1,,3,4'");
  EXPECT_EQ(PriorError("1,2,north,4"), "'north' is not a number; " + expected + "'1,2,north,4'");
  EXPECT_EQ(PriorError("1,2,3,inf"), "'inf' is not a number; " + expected + "'1,2,3,inf'");
  EXPECT_EQ(PriorError("1,2,0"), "RADIUS_M must be > 0, got '1,2,0'");
  EXPECT_EQ(PriorError("1,2,3,0"), "RADIUS_M must be > 0, got '1,2,3,0'");
}

v1::RelocalizeResponse Localized(double yaw_deg) {
  v1::RelocalizeResponse response;
  response.set_status(v1::RelocalizeResponse::STATUS_LOCALIZED);
  v1::Pose* pose = response.mutable_map_from_sensor();
  pose->mutable_translation()->set_x(1.5);
  pose->mutable_translation()->set_y(-2);
  pose->mutable_translation()->set_z(0.25);
  pose->mutable_rotation()->set_z(std::sin(yaw_deg * M_PI / 360));
  pose->mutable_rotation()->set_w(std::cos(yaw_deg * M_PI / 360));
  response.set_inliers(42);
  response.set_rmse_m(0.125);
  response.set_confidence(0.5);
  response.set_server_time_ms(3.25);
  return response;
}

TEST(CliFormatTest, RelocalizeJsonHasTheDocumentedKeysInOrder) {
  const nlohmann::ordered_json line = RelocalizeJson(Localized(-120), 17);
  std::vector<std::string> keys;
  for (const auto& item : line.items()) keys.push_back(item.key());
  const std::vector<std::string> expected = {"frame",
                                             "status",
                                             "x",
                                             "y",
                                             "z",
                                             "qx",
                                             "qy",
                                             "qz",
                                             "qw",
                                             "yaw_deg",
                                             "inliers",
                                             "rmse_m",
                                             "confidence",
                                             "coverage_share",
                                             "trees_in_coverage",
                                             "server_ms"};
  EXPECT_EQ(keys, expected);
  EXPECT_EQ(line["frame"], 17);
  EXPECT_EQ(line["status"], "localized");
  EXPECT_EQ(line["x"], 1.5);
  EXPECT_NEAR(line["yaw_deg"].get<double>(), -120, 1e-9);
  EXPECT_EQ(line["inliers"], 42);
  EXPECT_EQ(line["server_ms"], 3.25);
  // Compact, one line.
  EXPECT_EQ(line.dump().find('\n'), std::string::npos);
}

TEST(CliFormatTest, RelocalizeJsonWithoutPoseUnlessLocalized) {
  v1::RelocalizeResponse response;
  response.set_status(v1::RelocalizeResponse::STATUS_AMBIGUOUS);
  response.set_inliers(8);
  response.set_coverage_share(0.5);
  response.set_trees_in_coverage(12);
  EXPECT_EQ(RelocalizeJson(response).dump(),
            R"({"status":"ambiguous","inliers":8,"rmse_m":0.0,"confidence":0.0,)"
            R"("coverage_share":0.5,"trees_in_coverage":12,"server_ms":0.0})");
  response.set_status(v1::RelocalizeResponse::STATUS_NOT_FOUND);
  response.set_detail("best pose matches 3 trees");
  EXPECT_EQ(RelocalizeJson(response)["status"], "not_found");
  EXPECT_EQ(RelocalizeJson(response)["detail"], "best pose matches 3 trees");
}

TEST(CliFormatTest, RelocalizeJsonNamesTheMapAndAnotherMapsRival) {
  v1::RelocalizeResponse response = Localized(0);
  response.set_map_name("district-b");
  nlohmann::ordered_json line = RelocalizeJson(response);
  EXPECT_EQ(std::next(line.begin()).key(), "map");
  EXPECT_EQ(line["map"], "district-b");
  EXPECT_FALSE(line.contains("rival_map"));
  response.set_status(v1::RelocalizeResponse::STATUS_AMBIGUOUS);
  response.set_rival_map_name("district-c");
  line = RelocalizeJson(response);
  EXPECT_EQ(line["rival_map"], "district-c");
}

TEST(CliFormatTest, YawIsTheHeadingOfTheSensorXAxis) {
  // A sensor pitched 30 deg about its y axis, then turned 75 deg about map z.
  algorithms::Pose3 map_from_sensor = algorithms::Pose3::Identity();
  map_from_sensor.linear() = (Eigen::AngleAxisd(75 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(30 * M_PI / 180, Eigen::Vector3d::UnitY()))
                                 .toRotationMatrix();
  EXPECT_NEAR(YawDegrees(map_from_sensor), 75, 1e-9);
}

TEST(CliFormatTest, MapTableAlignsColumns) {
  v1::Map a;
  a.set_name("plot");
  a.set_tree_count(1418);
  a.set_version(3);
  a.set_crs("EPSG:2959");
  a.mutable_extent()->set_min_x(0);
  a.mutable_extent()->set_max_x(49.97);
  a.mutable_extent()->set_min_y(-60);
  a.mutable_extent()->set_max_y(-0.1);
  v1::Map b;
  b.set_name("a-much-longer-name");
  b.set_version(1);
  EXPECT_EQ(FormatMapTable({a, b}),
            "NAME                TREES  VERSION  CRS        EXTENT\n"
            "plot                1418   3        EPSG:2959  x 0.00..49.97 m, y -60.00..-0.10 m\n"
            "a-much-longer-name  0      1        -          -\n");
  EXPECT_EQ(FormatMapTable({}), "NAME  TREES  VERSION  CRS  EXTENT\n");
}

// `map list` was padded to ~2,084 characters a row once one map had a WKT CRS.
TEST(CliFormatTest, MapTableShowsAShortCrs) {
  // WKT2: the outermost ID wins over the base CRS's ID["EPSG",4326] inside.
  const std::string wkt2 =
      "PROJCRS[\"WGS 84 / UTM zone 33N\",BASEGEOGCRS[\"WGS 84\",DATUM[\"World Geodetic System "
      "1984\",ELLIPSOID[\"WGS 84\",6378137,298.257223563]],ID[\"EPSG\",4326]],CONVERSION[\"UTM "
      "zone 33N\",METHOD[\"Transverse Mercator\",ID[\"EPSG\",9807]]],CS[Cartesian,2],"
      "USAGE[SCOPE[\"Engineering survey, [topographic] mapping.\"],BBOX[0,12,84,18]],"
      "ID[\"EPSG\",32633]]";
  EXPECT_EQ(ListedCrs(wkt2), "EPSG:32633");
  const std::string wkt1 =
      "PROJCS[\"NZGD2000 / New Zealand Transverse Mercator 2000\",GEOGCS[\"NZGD2000\","
      "AUTHORITY[\"EPSG\",\"4167\"]],UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"2193\"]]";
  EXPECT_EQ(ListedCrs(wkt1), "EPSG:2193");
  // No ID of its own: the name, cut to 32 characters.
  EXPECT_EQ(ListedCrs("PROJCRS[\"Forest grid\",BASEGEOGCRS[\"x\",ID[\"EPSG\",4326]],CS[]]"),
            "Forest grid");
  EXPECT_EQ(ListedCrs("ENGCRS[\"A very long local engineering grid name, version 2\",EDATUM[]]"),
            "A very long local engineering...");
  EXPECT_EQ(ListedCrs("EPSG:2959"), "EPSG:2959");
  EXPECT_EQ(ListedCrs(""), "-");
  EXPECT_EQ(ListedCrs("+proj=tmerc +lat_0=0 +lon_0=173 +k=0.9996 +x_0=1600000 +units=m"),
            "+proj=tmerc +lat_0=0 +lon_0=1...");

  v1::Map map;
  map.set_name("nz");
  map.set_crs(wkt1 + std::string(2000, ' '));
  const std::string table = FormatMapTable({map});
  EXPECT_EQ(table,
            "NAME  TREES  VERSION  CRS        EXTENT\n"
            "nz    0      0        EPSG:2193  -\n");
  EXPECT_NE(FormatMapDetails(map).find(wkt1), std::string::npos);  // `map show`: the whole
}

// Progress of uploads, exports and writes: at most one line per tenth of the trees, and the last
// (was one per message), whatever the steps; nothing for a job of one chunk.
TEST(CliFormatTest, ProgressEveryTenth) {
  constexpr int64_t kChunk = 5000;
  for (const int64_t total : {int64_t{10'001}, int64_t{1'000'000}, int64_t{123'456}}) {
    for (const int64_t step : {kChunk, int64_t{1}, int64_t{777}}) {
      std::ostringstream err;
      const auto progress = ProgressTo(err, "exporting", total, kChunk);
      for (int64_t done = std::min(step, total); done <= total;
           done = done == total ? total + 1 : std::min(done + step, total)) {
        progress(done);
      }
      const std::string text = err.str();
      const auto lines = std::count(text.begin(), text.end(), '\n');
      EXPECT_LE(lines, 10) << total << " by " << step;
      EXPECT_GE(lines, std::min<int64_t>(10, (total + step - 1) / step)) << total << " by " << step;
      EXPECT_NE(text.find("exporting: " + std::to_string(total) + "/" + std::to_string(total) +
                          " trees\n"),
                std::string::npos)
          << text;
    }
  }
  EXPECT_FALSE(ProgressTo(std::cerr, "exporting", kChunk, kChunk));
}

// A map's name, description and CRS come from the server: printed raw, an escape sequence in
// them would drive the user's terminal (retitle it, hide text, move the cursor).
TEST(CliFormatTest, MapTextNeverPrintsTerminalControlCharacters) {
  v1::Map map;
  map.set_name("plot\x1b]0;owned\x07");
  map.set_description(
      "line one\nfake: field\x1b[2J\r\x7f and \xc2\x9b"
      "31m, caf\xc3\xa9");
  map.set_crs("EPSG:2193\x1b[8m");
  for (const std::string& text : {FormatMapDetails(map), FormatMapTable({map})}) {
    for (const char c : text) {
      const unsigned char byte = static_cast<unsigned char>(c);
      EXPECT_TRUE(c == '\n' || (byte >= 0x20 && byte != 0x7f)) << "raw byte " << int{byte};
    }
    EXPECT_EQ(text.find("\xc2\x9b"), std::string::npos);  // the C1 control sequence introducer
    EXPECT_NE(text.find("plot\\x1b]0;owned\\x07"), std::string::npos) << text;
  }
  const std::string details = FormatMapDetails(map);
  EXPECT_NE(details.find("description: line one\\nfake: field\\x1b[2J\\r\\x7f and \\u009b31m, "
                         "caf\xc3\xa9\n"),
            std::string::npos)
      << details;
  EXPECT_NE(details.find("crs:         EPSG:2193\\x1b[8m\n"), std::string::npos) << details;
}

TEST(CliFormatTest, MapDetails) {
  v1::Map map;
  map.set_name("plot");
  map.set_version(2);
  map.set_tree_count(10);
  map.set_created_unix_ms(1700000000123);
  EXPECT_EQ(FormatMapDetails(map),
            "name:        plot\n"
            "description: -\n"
            "crs:         -\n"
            "version:     2\n"
            "trees:       10\n"
            "extent:      -\n"
            "boundary:    no\n"
            "created:     2023-11-14T22:13:20Z\n"
            "updated:     -\n");
  map.set_has_boundary(true);
  EXPECT_NE(FormatMapDetails(map).find("\nboundary:    yes\n"), std::string::npos);
}

}  // namespace
}  // namespace forestmap::client
