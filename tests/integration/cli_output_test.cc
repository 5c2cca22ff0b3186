// What `forestmap` prints against a real forestmapd: upload progress at most every tenth of the
// trees (it printed one line per 5,000-tree message: 200 lines for a million trees, also into
// log files), and `map list` with a WKT CRS (every row was padded to the WKT's ~2,000 characters).

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "daemon_process.h"
#include "geo/crs.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;

constexpr int kUploadTrees = 100'000;  // 20 messages of 5,000 trees
constexpr int kMaxProgressLines = 11;  // one per tenth, and the last
constexpr size_t kMaxListLine = 120;   // characters of a `map list` row, at most

int CountLines(const std::string& text, const std::string& prefix) {
  std::istringstream lines(text);
  int count = 0;
  for (std::string line; std::getline(lines, line);) count += line.rfind(prefix, 0) == 0;
  return count;
}

class CliOutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cli_output_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ASSERT_TRUE(daemon_.Start("--db '" + (dir_ / "maps.db").string() + "' --listen 127.0.0.1:0",
                              dir_ / "server.log", dir_ / "pid"));
  }
  void TearDown() override {
    daemon_.Stop();
    fs::remove_all(dir_);
  }
  CommandResult Client(const std::string& args) {
    return test::RunShell(test::ClientCommand(daemon_.address(), args), dir_ / "out", dir_ / "err");
  }

  fs::path dir_;
  test::DaemonProcess daemon_;
};

TEST_F(CliOutputTest, UploadProgressAtMostEveryTenth) {
  const fs::path csv = dir_ / "trees.csv";
  {
    std::ofstream out(csv);
    out << "id,x,y,dbh\n";
    for (int i = 0; i < kUploadTrees; ++i) {
      out << i << "," << (i % 400) * 5 << "," << (i / 400) * 5 << ",0.3\n";
    }
  }
  for (const std::string& command : {"map create big --trees '" + csv.string() + "'",
                                     "map upload big --trees '" + csv.string() + "' --replace"}) {
    const CommandResult result = Client(command);  // stderr is a file, not a terminal
    ASSERT_EQ(result.exit_code, 0) << result.err;
    const int lines = CountLines(result.err, "uploading: ");
    EXPECT_GE(lines, 2) << result.err;
    EXPECT_LE(lines, kMaxProgressLines) << result.err;
    EXPECT_NE(result.err.find("uploading: 100000/100000 trees"), std::string::npos) << result.err;
  }
  // The way back: the download and the GeoPackage's writing, each at most every tenth.
  const CommandResult exported =
      Client("map export big --out '" + (dir_ / "big.gpkg").string() + "'");
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_LE(CountLines(exported.err, "exporting: "), 10) << exported.err;
  EXPECT_NE(exported.err.find("exporting: 100000/100000 trees"), std::string::npos) << exported.err;
  EXPECT_LE(CountLines(exported.err, "writing "), 10) << exported.err;
  EXPECT_NE(exported.err.find(": 100000/100000 trees\nexported 100000 trees"), std::string::npos)
      << exported.err;
}

TEST_F(CliOutputTest, ListingsPrintOneJsonObjectPerLineWithJson) {
  ASSERT_EQ(Client("map create plot --crs EPSG:2193 --description 'north plot'").exit_code, 0);
  ASSERT_EQ(Client("map create empty").exit_code, 0);
  const fs::path csv = dir_ / "trees.csv";
  std::ofstream(csv) << "id,x,y,dbh\n1,0,0,0.3\n2,5,1,0.2\n3,2,7,0.4\n";
  ASSERT_EQ(Client("map upload plot --trees '" + csv.string() + "'").exit_code, 0);

  const CommandResult list = Client("map list --json");
  ASSERT_EQ(list.exit_code, 0) << list.err;
  std::vector<nlohmann::json> maps;
  std::istringstream lines(list.out);
  for (std::string line; std::getline(lines, line);) maps.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(maps.size(), 2u) << list.out;
  EXPECT_EQ(maps[0]["name"], "empty");
  EXPECT_TRUE(maps[0]["extent"].is_null());
  EXPECT_EQ(maps[1]["name"], "plot");
  EXPECT_EQ(maps[1]["trees"], 3);
  EXPECT_EQ(maps[1]["epsg"], 2193);
  EXPECT_EQ(maps[1]["extent"], nlohmann::json::parse("[0.0, 0.0, 5.0, 7.0]"));

  const CommandResult show = Client("map show plot --json");
  ASSERT_EQ(show.exit_code, 0) << show.err;
  const nlohmann::json plot = nlohmann::json::parse(show.out);
  EXPECT_EQ(plot["description"], "north plot");
  EXPECT_EQ(plot["version"], 2);

  const CommandResult history = Client("map history plot --json");
  ASSERT_EQ(history.exit_code, 0) << history.err;
  std::istringstream versions(history.out);
  std::string first, second;
  ASSERT_TRUE(std::getline(versions, first) && std::getline(versions, second)) << history.out;
  EXPECT_EQ(nlohmann::json::parse(first)["kind"], "create");
  EXPECT_EQ(nlohmann::json::parse(second)["trees_added"], 3);
}

TEST_F(CliOutputTest, MapListShowsAShortCrsAndMapShowTheWhole) {
  // A CRS without an EPSG code is stored as WKT: a transverse Mercator grid of our own name.
  std::string wkt = geo::ParseCrs(
                        "+proj=tmerc +lat_0=0 +lon_0=173 +k=0.9996 +x_0=1600001 +y_0=10000000 "
                        "+ellps=GRS80 +units=m +no_defs +type=crs")
                        .wkt;
  const size_t name = wkt.find("[\"unknown\"");
  ASSERT_NE(name, std::string::npos) << wkt;
  wkt.replace(name, 10, "[\"Forest grid TM 173E\"");
  ASSERT_EQ(Client("map create grid --crs '" + wkt + "'").exit_code, 0);
  ASSERT_EQ(Client("map create plot --crs EPSG:2193").exit_code, 0);

  const CommandResult list = Client("map list");
  ASSERT_EQ(list.exit_code, 0) << list.err;
  std::istringstream rows(list.out);
  for (std::string row; std::getline(rows, row);) EXPECT_LE(row.size(), kMaxListLine) << row;
  EXPECT_NE(list.out.find("grid  0      1        Forest grid TM 173E  -"), std::string::npos)
      << list.out;
  EXPECT_NE(list.out.find("plot  0      1        EPSG:2193"), std::string::npos) << list.out;

  const CommandResult show = Client("map show grid");
  ASSERT_EQ(show.exit_code, 0) << show.err;
  EXPECT_NE(show.out.find("Forest grid TM 173E\",BASEGEOGCRS["), std::string::npos) << show.out;
  EXPECT_GT(show.out.size(), 500u);
}

}  // namespace
}  // namespace forestmap
