// `forestmap map changes` against the built forestmapd: a surveyed plot re-surveyed with trees
// felled, trees grown in, one DBH grown and one tree re-measured 0.5 m away; the command reports
// exactly those, by version and by date, as a table, JSON, CSV, GeoJSON and GeoPackage (read back
// with GDAL's ogrinfo), and refuses what it cannot compare with one clear line.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon_process.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;

// The first survey (UTM 18N, inside EPSG:2959's area), then the second: trees 3 and 7 felled,
// 11 and 12 new, tree 2's DBH 0.40 -> 0.45 m (grown), tree 5 re-measured 0.5 m east (moved),
// tree 4 at 1 cm and 2 cm from where it was and 1 cm thicker: within a survey's precision.
constexpr const char* kFirstSurvey =
    "id,x,y,dbh\n"
    "1,500000,5000000,0.30\n2,500010,5000000,0.40\n3,500000,5000010,0.20\n"
    "4,500010,5000010,0.50\n5,500005,5000005,0.25\n6,500020,5000000,0.35\n"
    "7,500020,5000010,0.32\n";
constexpr const char* kSecondSurvey =
    "id,x,y,dbh\n"
    "1,500000,5000000,0.30\n2,500010,5000000,0.45\n4,500010.01,5000010.02,0.51\n"
    "5,500005.5,5000005,0.25\n6,500020,5000000,0.35\n11,500030,5000030,0.08\n"
    "12,500031,5000020,0.10\n";

std::string IsoTime(int64_t unix_ms) {
  const std::time_t seconds = static_cast<std::time_t>(unix_ms / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

class ChangesCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("changes_cli_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ASSERT_TRUE(daemon_.Start("--db '" + (dir_ / "maps.db").string() + "' --listen 127.0.0.1:0",
                              dir_ / "server.log", dir_ / "pid"));
    std::ofstream(dir_ / "first.csv") << kFirstSurvey;
    std::ofstream(dir_ / "second.csv") << kSecondSurvey;
    const CommandResult created =
        Client("map create plot --crs EPSG:2959 --trees '" + (dir_ / "first.csv").string() + "'");
    ASSERT_EQ(created.exit_code, 0) << created.err;
    // Versions a second apart, so that a date in between names one of them.
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    const CommandResult replaced =
        Client("map upload plot --replace --trees '" + (dir_ / "second.csv").string() + "'");
    ASSERT_EQ(replaced.exit_code, 0) << replaced.err;
    const CommandResult history = Client("map history plot --json");
    ASSERT_EQ(history.exit_code, 0) << history.err;
    std::istringstream lines(history.out);
    for (std::string line; std::getline(lines, line);)
      versions_.push_back(nlohmann::json::parse(line));
    ASSERT_EQ(versions_.size(), 3u) << history.out;  // create, the first survey, the second
  }
  void TearDown() override {
    daemon_.Stop();
    fs::remove_all(dir_);
  }
  CommandResult Client(const std::string& args) {
    return test::RunShell(test::ClientCommand(daemon_.address(), args), dir_ / "out", dir_ / "err");
  }
  CommandResult Shell(const std::string& command) {
    return test::RunShell(command, dir_ / "out", dir_ / "err");
  }
  int64_t Version(size_t i) const { return versions_[i]["version"].get<int64_t>(); }

  fs::path dir_;
  test::DaemonProcess daemon_;
  std::vector<nlohmann::json> versions_;  // map history, oldest first
};

// kind -> ids, from the JSON answer.
std::map<std::string, std::set<int64_t>> IdsByKind(const nlohmann::json& answer) {
  std::map<std::string, std::set<int64_t>> ids;
  for (const nlohmann::json& change : answer["changes"]) {
    ids[change["change"].get<std::string>()].insert(change["id"].get<int64_t>());
  }
  return ids;
}

const std::map<std::string, std::set<int64_t>> kExpected = {
    {"removed", {3, 7}}, {"new", {11, 12}}, {"grown", {2}}, {"moved", {5}}};

TEST_F(ChangesCliTest, ReportsExactlyTheTreesRemovedNewGrownAndMoved) {
  const std::string since = std::to_string(Version(1));
  const CommandResult table = Client("map changes plot --since " + since);
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("from version " + since + " (" +
                           IsoTime(versions_[1]["created_unix_ms"].get<int64_t>()) + ", 7 trees)"),
            std::string::npos)
      << table.out;
  EXPECT_NE(table.out.find("to   version " + std::to_string(Version(2))), std::string::npos)
      << table.out;
  for (const char* row :
       {"removed          2", "new              2", "grown            1", "moved            1"}) {
    EXPECT_NE(table.out.find(row), std::string::npos) << row << " in\n" << table.out;
  }

  const CommandResult json = Client("map changes plot --json --since " + since);
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const nlohmann::json answer = nlohmann::json::parse(json.out);
  EXPECT_EQ(IdsByKind(answer), kExpected) << json.out;
  EXPECT_EQ(answer["crs"], "EPSG:2959");
  for (const nlohmann::json& change : answer["changes"]) {
    if (change["change"] == "grown") {
      EXPECT_DOUBLE_EQ(change["dbh_change"].get<double>(), 0.05);
      EXPECT_NEAR(change["threshold"].get<double>(), 0.0283, 1e-9);  // 2 * hypot(1 cm, 1 cm)
    }
    if (change["change"] == "moved") {
      EXPECT_DOUBLE_EQ(change["dx"].get<double>(), 0.5);
      EXPECT_DOUBLE_EQ(change["distance"].get<double>(), 0.5);
      EXPECT_DOUBLE_EQ(change["x_before"].get<double>(), 500005);
    }
  }
  // Fixed thresholds: tree 4's 1 cm of DBH and 2.2 cm of distance count when asked to.
  const CommandResult strict = Client(
      "map changes plot --json --min-dbh-change 0.005 "
      "--min-move 0.02 --since " +
      since);
  ASSERT_EQ(strict.exit_code, 0) << strict.err;
  auto expected = kExpected;
  expected["grown"].insert(4);
  expected["moved"].insert(4);
  EXPECT_EQ(IdsByKind(nlohmann::json::parse(strict.out)), expected) << strict.out;
}

TEST_F(ChangesCliTest, ADateNamesTheLastVersionMadeAtOrBeforeIt) {
  // The second after the first survey's version: before the second survey (1.1 s later).
  const int64_t first_ms = versions_[1]["created_unix_ms"].get<int64_t>();
  const std::string after_first = IsoTime((first_ms / 1000 + 1) * 1000);
  const CommandResult by_date = Client("map changes plot --json --since " + after_first);
  ASSERT_EQ(by_date.exit_code, 0) << by_date.err;
  const nlohmann::json answer = nlohmann::json::parse(by_date.out);
  EXPECT_EQ(answer["from"]["version"], Version(1)) << after_first;
  EXPECT_EQ(IdsByKind(answer), kExpected);
  // The same instant an hour east of UTC.
  const int hour = std::stoi(after_first.substr(11, 2));
  if (hour < 23) {
    char next_hour[16];
    std::snprintf(next_hour, sizeof(next_hour), "%02d", hour + 1);
    std::string shifted = after_first;
    shifted.replace(11, 2, next_hour);
    shifted.back() = '+';
    shifted += "01:00";
    const CommandResult offset = Client("map changes plot --json --since " + shifted);
    ASSERT_EQ(offset.exit_code, 0) << offset.err;
    EXPECT_EQ(nlohmann::json::parse(offset.out)["from"]["version"], Version(1)) << shifted;
  }
  // A date after every version: the current one against itself, nothing changed.
  const CommandResult future = Client("map changes plot --json --since 2999-01-01");
  ASSERT_EQ(future.exit_code, 0) << future.err;
  const nlohmann::json nothing = nlohmann::json::parse(future.out);
  EXPECT_EQ(nothing["from"]["version"], Version(2));
  EXPECT_TRUE(nothing["changes"].empty());
  // --to by version: the first survey against the empty map it was uploaded into.
  const CommandResult to =
      Client("map changes plot --json --since 1 --to " + std::to_string(Version(1)));
  ASSERT_EQ(to.exit_code, 0) << to.err;
  EXPECT_EQ(nlohmann::json::parse(to.out)["counts"]["new"], 7);
}

TEST_F(ChangesCliTest, FilesReadBackWithGdal) {
  const std::string since = " --since " + std::to_string(Version(1));
  const std::string csv = (dir_ / "changes.csv").string();
  const CommandResult wrote_csv = Client("map changes plot --out '" + csv + "'" + since);
  ASSERT_EQ(wrote_csv.exit_code, 0) << wrote_csv.err;
  EXPECT_EQ(test::ReadFile(csv),
            "id,change,x,y,dbh_before,dbh_after,dbh_change,x_before,y_before,dx,dy,distance,"
            "threshold\n"
            "3,removed,500000,5000010,0.2,,,,,,,,\n"
            "7,removed,500020,5000010,0.32,,,,,,,,\n"
            "11,new,500030,5000030,,0.08,,,,,,,\n"
            "12,new,500031,5000020,,0.1,,,,,,,\n"
            "2,grown,500010,5000000,0.4,0.45,0.05,500010,5000000,0,0,0,0.0283\n"
            "5,moved,500005.5,5000005,0.25,0.25,0,500005,5000005,0.5,0,0.5,0.1731\n");
  EXPECT_TRUE(fs::exists(dir_ / "changes.prj"));  // the CRS beside it, as map export writes

  const std::string gpkg = (dir_ / "changes.gpkg").string();
  const CommandResult wrote_gpkg = Client("map changes plot --out '" + gpkg + "'" + since);
  ASSERT_EQ(wrote_gpkg.exit_code, 0) << wrote_gpkg.err;
  const std::map<std::string, int> counts = {
      {"removed", 2}, {"new", 2}, {"grown", 1}, {"moved", 1}};
  for (const auto& [layer, count] : counts) {
    const CommandResult info = Shell("ogrinfo -so '" + gpkg + "' " + layer);
    ASSERT_EQ(info.exit_code, 0) << info.err << " (is gdal-bin installed?)";
    EXPECT_NE(info.out.find("Feature Count: " + std::to_string(count)), std::string::npos)
        << layer << "\n"
        << info.out;
    EXPECT_NE(info.out.find("ID[\"EPSG\",2959]]"), std::string::npos) << info.out;
    EXPECT_NE(info.out.find("change: String"), std::string::npos) << info.out;
  }
  const CommandResult grown = Shell("ogrinfo -al -q '" + gpkg + "' grown");
  EXPECT_NE(grown.out.find("dbh_change (Real) = 0.05"), std::string::npos) << grown.out;
  EXPECT_NE(grown.out.find("dbh_before (Real) = 0.4"), std::string::npos) << grown.out;
  EXPECT_NE(grown.out.find("POINT (500010 5000000)"), std::string::npos) << grown.out;

  const std::string geojson = (dir_ / "changes.geojson").string();
  const CommandResult wrote_geojson = Client("map changes plot --out '" + geojson + "'" + since);
  ASSERT_EQ(wrote_geojson.exit_code, 0) << wrote_geojson.err;
  const CommandResult info = Shell("ogrinfo -so -al '" + geojson + "'");
  EXPECT_NE(info.out.find("Feature Count: 6"), std::string::npos) << info.out;
  const CommandResult removed =
      Shell("ogrinfo -al -q -where \"change = 'removed'\" '" + geojson + "'");
  EXPECT_NE(removed.out.find("id (Integer) = 3"), std::string::npos) << removed.out;
  EXPECT_NE(removed.out.find("id (Integer) = 7"), std::string::npos) << removed.out;
}

TEST_F(ChangesCliTest, RefusesWhatItCannotCompareWithOneLine) {
  struct Case {
    std::string args, message;
  };
  const std::string current = std::to_string(Version(2));
  for (const Case& c : std::vector<Case>{
           {"nosuch --since 1", "map 'nosuch' does not exist"},
           {"plot --since 99", "--since 99: map 'plot' has versions 1.." + current},
           {"plot --since 1 --to 99", "--to 99: map 'plot' has versions 1.." + current},
           {"plot --since 2001-05-01", "map 'plot' did not exist yet: it was created at"},
           {"plot --since " + current + " --to 1",
            "--since " + current + " (version " + current + ") is newer than --to 1 (version 1)"},
           {"plot --since last-week", "expected a version number or a date"},
           {"plot --since 2026-02-30", "expected a version number or a date"},
           {"plot --since 1 --out changes.shp", "name it .csv, .geojson or .gpkg"},
       }) {
    SCOPED_TRACE(c.args);
    const CommandResult result = Client("map changes " + c.args);
    EXPECT_EQ(result.exit_code, 1);
    EXPECT_NE(result.err.find("forestmap: error: " + std::string()), std::string::npos);
    EXPECT_NE(result.err.find(c.message), std::string::npos) << result.err;
  }
  const CommandResult missing = Client("map changes plot");
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("--since is required"), std::string::npos) << missing.err;
  const CommandResult help = Client("map changes --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("Usage: forestmap map changes"), std::string::npos) << help.out;
}

}  // namespace
}  // namespace forestmap
