// forestmapd's HTTP listeners as an operator runs them (the built binaries): --http or --metrics
// on a port already in use, or a malformed address, is an error at start-up naming the flag and
// the address (before, cpp-httplib's SO_REUSEPORT let a second server share the port and take
// half of its requests); the web page's tree route keeps the server's memory bounded on a
// 300,000-tree map (before, every request kept ~85 MB in the arena of an HTTP thread); `--help`
// and the usage block of docs/operations.md list every flag; the names "." and ".." are refused;
// OGC API - Features serves a surveyed map and its survey boundary to GDAL (ogrinfo, ogr2ogr) in
// WGS 84 as cs2cs moves them, behind tokens, and pages a huge map in bounded memory.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "daemon_process.h"
#include "storage/sqlite/store.h"
#include "tests/server/http_get.h"
#include "tests/shared_data.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using test::ReadFile;

constexpr int kHugeMapTrees = 300'000;  // the trial's map: a 9 MB JSON answer
constexpr int kTreeRequests = 14;       // sequential GETs of it (the trial's count)
// RSS growth allowed over those requests. Measured 36 MiB streamed (SQLite page cache, arenas of
// the 8 HTTP threads), 707 MiB when each request built its whole JSON document.
constexpr int64_t kRssGrowthBoundMib = 150;
constexpr int64_t kKibPerMib = 1024;

// "--flag" words in `text`.
std::set<std::string> Flags(const std::string& text) {
  std::set<std::string> flags;
  const std::regex flag(R"(--[a-z][a-z0-9-]*)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), flag); it != std::sregex_iterator();
       ++it) {
    flags.insert(it->str());
  }
  return flags;
}

int64_t RssMib(int pid) {
  const std::string status = ReadFile("/proc/" + std::to_string(pid) + "/status");
  std::smatch match;
  if (!std::regex_search(status, match, std::regex(R"(VmRSS:\s+(\d+) kB)"))) return -1;
  return std::stoll(match[1].str()) / kKibPerMib;
}

class DaemonHttpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("daemon_http_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    daemon_.Stop();
    fs::remove_all(dir_);
  }

  CommandResult Run(const std::string& command) {
    return test::RunShell(command, dir_ / "stdout", dir_ / "stderr");
  }
  // A second forestmapd on its own database with `flags`; it must exit (timeout: 124).
  CommandResult SecondDaemon(const std::string& flags) {
    return Run("timeout 15 '" FORESTMAPD_PATH "' --db '" + (dir_ / "second.db").string() +
               "' --listen 127.0.0.1:0 " + flags);
  }
  // Starts the first forestmapd with --http 127.0.0.1:0 and returns the page's port.
  // A new token of `role` on `map` in first.db, made by `forestmapd token create`.
  std::string Token(const std::string& map, const std::string& role) {
    const CommandResult created =
        Run("'" FORESTMAPD_PATH "' token create --db '" + (dir_ / "first.db").string() +
            "' --map '" + map + "' --role " + role);
    std::string secret = created.out;
    while (!secret.empty() && secret.back() == '\n') secret.pop_back();
    return secret;
  }

  int ServeWithPage(const std::string& flags = "") {
    const fs::path log = dir_ / "first.log";
    EXPECT_TRUE(daemon_.Start("--db '" + (dir_ / "first.db").string() +
                                  "' --listen 127.0.0.1:0 --http 127.0.0.1:0 " + flags,
                              log, dir_ / "pid"));
    std::smatch match;
    const std::string text = ReadFile(log);
    EXPECT_TRUE(std::regex_search(text, match, std::regex(R"(web page on http://[^:]+:(\d+)/)")))
        << text;
    return match.empty() ? 0 : std::stoi(match[1].str());
  }

  // Map "huge" of kHugeMapTrees trees on a 5.5 m grid in the first server's database.
  std::vector<storage::TreeRecord> WriteHugeMap() {
    std::vector<storage::TreeRecord> trees(kHugeMapTrees);
    for (int i = 0; i < kHugeMapTrees; ++i) {
      trees[i].x = (i % 550) * 5.5;
      trees[i].y = (i / 550) * 5.5;
      trees[i].dbh = 0.1 + (i % 60) * 0.01;
    }
    storage::SqliteMapStore store((dir_ / "first.db").string());
    store.CreateMap("huge", "", "");
    store.WriteTrees("huge", trees, storage::WriteMode::kReplace);
    return trees;
  }

  fs::path dir_;
  test::DaemonProcess daemon_;
};

TEST_F(DaemonHttpTest, HttpOrMetricsOnAPortInUseIsAStartUpError) {
  const int port = ServeWithPage();
  ASSERT_GT(port, 0);
  const std::string taken = "127.0.0.1:" + std::to_string(port);
  for (const std::string flag : {"--http", "--metrics"}) {
    const CommandResult second = SecondDaemon(flag + " " + taken);
    EXPECT_EQ(second.exit_code, 1) << second.err;
    EXPECT_NE(second.err.find("error " + flag + " " + taken + ": address already in use"),
              std::string::npos)
        << second.err;
    EXPECT_EQ(second.err.find("serving on"), std::string::npos) << second.err;
    EXPECT_EQ(second.err.find("web page on"), std::string::npos) << second.err;
  }
  // The first server still answers, alone on its port.
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, "/api/maps").body, "[]");
}

TEST_F(DaemonHttpTest, MalformedHttpAddressIsAStartUpError) {
  for (const std::string address : {"localhost", "127.0.0.1:http", "127.0.0.1:65536"}) {
    const CommandResult second = SecondDaemon("--http " + address);
    EXPECT_EQ(second.exit_code, 1) << second.err;
    EXPECT_NE(second.err.find("error --http " + address + ": give host:port"), std::string::npos)
        << second.err;
    EXPECT_EQ(second.err.find("serving on"), std::string::npos) << second.err;
  }
}

TEST_F(DaemonHttpTest, TreeRequestsOnAHugeMapKeepMemoryBounded) {
  const std::vector<storage::TreeRecord> trees = WriteHugeMap();
  const int port = ServeWithPage();
  ASSERT_GT(port, 0);
  const int pid = std::stoi(ReadFile(dir_ / "pid"));
  const int64_t before = RssMib(pid);
  ASSERT_GT(before, 0);
  for (int request = 0; request < kTreeRequests; ++request) {
    const test::HttpAnswer answer = test::HttpGet("127.0.0.1", port, "/api/maps/huge/trees");
    ASSERT_EQ(answer.status, 200);
    EXPECT_EQ(answer.transfer_encoding, "chunked");
    if (request == 0) {  // the whole map, every value bit for bit
      const nlohmann::json body = nlohmann::json::parse(answer.body);
      ASSERT_EQ(body["trees"].size(), trees.size());
      for (size_t i = 0; i < trees.size(); ++i) {
        const nlohmann::json& tree = body["trees"][i];
        ASSERT_EQ(tree[0].get<double>(), trees[i].x) << "tree " << i;
        ASSERT_EQ(tree[1].get<double>(), trees[i].y) << "tree " << i;
        ASSERT_EQ(tree[2].get<double>(), *trees[i].dbh) << "tree " << i;
      }
    }
  }
  const int64_t growth = RssMib(pid) - before;
  RecordProperty("rss_growth_mib", std::to_string(growth));
  EXPECT_LE(growth, kRssGrowthBoundMib) << "RSS " << before << " MiB before, +" << growth;
}

TEST_F(DaemonHttpTest, UsageAndOperationsPageListEveryFlag) {
  const CommandResult help = Run("'" FORESTMAPD_PATH "' --help");
  ASSERT_EQ(help.exit_code, 0) << help.err;
  const size_t options = help.out.find("\nOptions:");
  const size_t cli11_usage = help.out.find("\nUsage: ", help.out.find("Usage: ") + 1);
  ASSERT_NE(options, std::string::npos) << help.out;
  ASSERT_NE(cli11_usage, std::string::npos) << help.out;
  const std::set<std::string> flags = Flags(help.out.substr(options));
  ASSERT_GE(flags.size(), 14u) << help.out;
  const std::set<std::string> banner = Flags(help.out.substr(0, cli11_usage));

  const std::string page = ReadFile(FORESTMAP_SOURCE_DIR "/docs/operations.md");
  const size_t block = page.find("```\nforestmapd [--db");
  ASSERT_NE(block, std::string::npos) << "no forestmapd usage block in docs/operations.md";
  const std::set<std::string> page_flags =
      Flags(page.substr(block, page.find("```", block + 3) - block));
  for (const std::string& flag : flags) {
    EXPECT_TRUE(banner.count(flag)) << flag << " is missing from the usage banner";
    EXPECT_TRUE(page_flags.count(flag))
        << flag << " is missing from docs/operations.md's usage block";
  }
}

TEST_F(DaemonHttpTest, DotNamesAreRefused) {
  ServeWithPage();
  for (const std::string name : {".", ".."}) {
    const CommandResult create =
        Run(test::ClientCommand(daemon_.address(), "map create '" + name + "'"));
    EXPECT_EQ(create.exit_code, 1) << create.err;
    EXPECT_NE(create.err.find("INVALID_ARGUMENT"), std::string::npos) << create.err;
    EXPECT_NE(create.err.find("must not be \".\" or \"..\""), std::string::npos) << create.err;
  }
  const CommandResult list = Run(test::ClientCommand(daemon_.address(), "map list"));
  EXPECT_EQ(list.out, "NAME  TREES  VERSION  CRS  EXTENT\n");
}

// The PRF025 field survey (EPSG:2959) as a GIS user reaches it through GDAL's OAPIF driver.
TEST_F(DaemonHttpTest, OgcApiFeaturesServesASurveyToGdal) {
  const std::string survey = FORESTMAP_SHARED_DATA "/survey_vs_lidar/PRF025/PRF025_Field.csv";
  if (!fs::exists(survey)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << survey;
  const std::string reader = Token("prf", "read"), admin = Token("*", "admin");
  ASSERT_FALSE(reader.empty());
  const int port = ServeWithPage();
  ASSERT_GT(port, 0);
  ASSERT_EQ(Run(test::ClientCommand(daemon_.address(),
                                    "map create prf --crs EPSG:2959 --trees '" + survey +
                                        "' --columns x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree "
                                        "--dbh-unit cm",
                                    "FORESTMAP_TOKEN=" + admin))
                .exit_code,
            0);
  const std::string source = "OAPIF:http://127.0.0.1:" + std::to_string(port) + "/ogc";
  const std::string with_token = "GDAL_HTTP_HEADERS='Authorization: Bearer " + reader + "' ";

  // Without a token GDAL gets 401; with the read token it sees the map in WGS 84.
  EXPECT_NE(Run("ogrinfo -ro -so '" + source + "' prf").exit_code, 0);
  const CommandResult info = Run(with_token + "ogrinfo -ro -so '" + source + "' prf");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("Feature Count: 62"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("ID[\"EPSG\",4326]"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("survey_Status: String"), std::string::npos) << info.out;

  // ogr2ogr pages it (7 trees a page) into a GeoPackage: every tree, where cs2cs puts it.
  const std::string gpkg = (dir_ / "prf.gpkg").string();
  const CommandResult copy =
      Run(with_token + "ogr2ogr -f GPKG '" + gpkg + "' '" + source + "' prf -oo PAGE_SIZE=7");
  ASSERT_EQ(copy.exit_code, 0) << copy.err;
  const CommandResult tree1 = Run("ogrinfo -ro -q '" + gpkg + "' prf -where 'tree_id = 1'");
  EXPECT_NE(tree1.out.find("dbh_m (Real) = 0.149"), std::string::npos) << tree1.out;
  const CommandResult count = Run("ogrinfo -ro -so '" + gpkg + "' prf");
  EXPECT_NE(count.out.find("Feature Count: 62"), std::string::npos) << count.out;
  // Tree 1 of the survey: Field_Xpj 312030.0203, Field_Ypj 5096043.185.
  const CommandResult expected =
      Run("echo '312030.0203 5096043.185' | cs2cs -f %.7f EPSG:2959 OGC:CRS84");
  double lon = 0, lat = 0;
  ASSERT_EQ(std::sscanf(expected.out.c_str(), "%lf %lf", &lon, &lat), 2) << expected.out;
  char point[64];
  std::snprintf(point, sizeof(point), "POINT (%.7f %.7f)", lon, lat);
  const CommandResult rounded = Run("ogrinfo -ro -q '" + gpkg + "' prf -where 'tree_id = 1' " +
                                    "-dialect sqlite -sql \"SELECT printf('POINT (%.7f %.7f)', " +
                                    "ST_X(geom), ST_Y(geom)) AS p FROM prf WHERE tree_id = 1\"");
  EXPECT_NE(rounded.out.find(point), std::string::npos) << rounded.out << " vs " << point;

  // The storage CRS on request; a bbox in it selects exactly the trees inside.
  const std::string items = "/ogc/collections/prf/items";
  const test::HttpAnswer projected =
      test::HttpGet("127.0.0.1", port,
                    items + "?limit=100&crs=http://www.opengis.net/def/crs/EPSG/0/2959", reader);
  ASSERT_EQ(projected.status, 200) << projected.body;
  const nlohmann::json all = nlohmann::json::parse(projected.body)["features"];
  ASSERT_EQ(all.size(), 62u);
  EXPECT_EQ(all[0]["geometry"]["coordinates"][0].get<double>(), 312030.0203);
  const double x0 = 312025, y0 = 5096040, x1 = 312040, y1 = 5096060;
  int inside = 0;
  for (const nlohmann::json& feature : all) {
    const double x = feature["geometry"]["coordinates"][0],
                 y = feature["geometry"]["coordinates"][1];
    inside += x >= x0 && x <= x1 && y >= y0 && y <= y1;
  }
  ASSERT_GT(inside, 0);
  ASSERT_LT(inside, 62);
  const test::HttpAnswer boxed = test::HttpGet(
      "127.0.0.1", port,
      items +
          "?limit=100&bbox=312025,5096040,312040,5096060&bbox-crs=http://www.opengis.net/def/"
          "crs/EPSG/0/2959",
      reader);
  EXPECT_EQ(nlohmann::json::parse(boxed.body)["numberReturned"], inside) << boxed.body;

  // Malformed requests: 400 with the reason; an unknown map 404, another map's 403.
  for (const std::string bad : {"?limit=0", "?limit=x", "?bbox=1,2,3", "?bbox=3,0,1,1",
                                "?crs=EPSG:4326", "?colour=red", "?bbox=nan,0,1,1"}) {
    const test::HttpAnswer answer = test::HttpGet("127.0.0.1", port, items + bad, reader);
    EXPECT_EQ(answer.status, 400) << bad << ": " << answer.body;
    EXPECT_NE(answer.body.find("InvalidParameterValue"), std::string::npos) << answer.body;
  }
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, "/ogc/collections/prf/items/99999", reader).status,
            404);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, "/ogc/collections/nosuch/items", admin).status, 404);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, "/ogc/collections/other/items", reader).status, 403);
}

// A map's survey boundary as a GIS user reaches it through GDAL's OAPIF driver: a second
// collection NAME:boundary beside the map's, one MultiPolygon where cs2cs puts it; `map show`
// says the map has one. The trees' survey columns keep the file's order.
TEST_F(DaemonHttpTest, OgcApiFeaturesServesTheSurveyBoundaryToGdal) {
  const std::string admin = Token("*", "admin"), other_reader = Token("other", "read");
  const int port = ServeWithPage();
  ASSERT_GT(port, 0);
  const auto cli = [&](const std::string& args) {
    return Run(test::ClientCommand(daemon_.address(), args, "FORESTMAP_TOKEN=" + admin));
  };
  std::ofstream(dir_ / "trees.csv")
      << "x,y,dbh,species,height,crown\n312030,5096043,0.2,oak,20,5\n312040,5096050,0.3,ash,18,4\n";
  std::ofstream(dir_ / "ring.csv")
      << "x,y\n312000,5096000\n312100,5096000\n312100,5096100\n312000,5096100\n";
  ASSERT_EQ(cli("map create plot --crs EPSG:2959 --trees '" + (dir_ / "trees.csv").string() +
                "' --boundary '" + (dir_ / "ring.csv").string() + "'")
                .exit_code,
            0);
  ASSERT_EQ(cli("map create other --crs EPSG:2959 --trees '" + (dir_ / "trees.csv").string() + "'")
                .exit_code,
            0);
  EXPECT_NE(cli("map show plot").out.find("boundary:    yes"), std::string::npos);
  EXPECT_NE(cli("map show other").out.find("boundary:    no"), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(cli("map show plot --json").out)["has_boundary"], true);

  const std::string source = "OAPIF:http://127.0.0.1:" + std::to_string(port) + "/ogc";
  const std::string with_token = "GDAL_HTTP_HEADERS='Authorization: Bearer " + admin + "' ";
  // The collections: both maps, and the boundary of the one that has one.
  const CommandResult layers = Run(with_token + "ogrinfo -ro -q '" + source + "'");
  ASSERT_EQ(layers.exit_code, 0) << layers.err;
  EXPECT_NE(layers.out.find(": plot "), std::string::npos) << layers.out;
  EXPECT_NE(layers.out.find(": other "), std::string::npos) << layers.out;
  EXPECT_NE(layers.out.find(": plot:boundary "), std::string::npos) << layers.out;
  EXPECT_EQ(layers.out.find("other:boundary"), std::string::npos) << layers.out;
  // The trees' survey columns come in the file's order, not by name.
  const CommandResult trees = Run(with_token + "ogrinfo -ro -so '" + source + "' plot");
  const size_t species = trees.out.find("\nspecies: "), height = trees.out.find("\nheight: "),
               crown = trees.out.find("\ncrown: ");
  ASSERT_NE(crown, std::string::npos) << trees.out;
  EXPECT_LT(species, height) << trees.out;
  EXPECT_LT(height, crown) << trees.out;
  const CommandResult info = Run(with_token + "ogrinfo -ro -so '" + source + "' plot:boundary");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("Feature Count: 1"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("Multi Polygon"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("ID[\"EPSG\",4326]"), std::string::npos) << info.out;

  // ogr2ogr copies it; its first vertex is where cs2cs moves the ring's first one.
  const std::string gpkg = (dir_ / "boundary.gpkg").string();
  const CommandResult copy = Run(with_token + "ogr2ogr -f GPKG '" + gpkg + "' '" + source +
                                 "' plot:boundary -nln boundary");
  ASSERT_EQ(copy.exit_code, 0) << copy.err;
  const CommandResult vertex =
      Run("ogrinfo -ro -q '" + gpkg + "' -dialect sqlite -sql \"SELECT printf('V %.7f %.7f', " +
          "ST_X(ST_PointN(ST_ExteriorRing(ST_GeometryN(geom, 1)), 1)), " +
          "ST_Y(ST_PointN(ST_ExteriorRing(ST_GeometryN(geom, 1)), 1))) AS v FROM boundary\"");
  const CommandResult expected = Run("echo '312000 5096000' | cs2cs -f %.7f EPSG:2959 OGC:CRS84");
  double lon = 0, lat = 0;
  ASSERT_EQ(std::sscanf(expected.out.c_str(), "%lf %lf", &lon, &lat), 2) << expected.out;
  char point[64];
  std::snprintf(point, sizeof(point), "V %.7f %.7f", lon, lat);
  EXPECT_NE(vertex.out.find(point), std::string::npos) << vertex.out << " vs " << point;

  // In the storage CRS: the ring as stored, closed; a bbox off it returns nothing.
  const std::string items = "/ogc/collections/plot:boundary/items";
  const test::HttpAnswer stored = test::HttpGet(
      "127.0.0.1", port, items + "?crs=http://www.opengis.net/def/crs/EPSG/0/2959", admin);
  ASSERT_EQ(stored.status, 200) << stored.body;
  const nlohmann::json ring =
      nlohmann::json::parse(stored.body)["features"][0]["geometry"]["coordinates"][0][0];
  ASSERT_EQ(ring.size(), 5u) << stored.body;
  EXPECT_EQ(ring[0], ring[4]);
  EXPECT_EQ(ring[2], nlohmann::json::parse("[312100.0, 5096100.0]"));
  const test::HttpAnswer missed = test::HttpGet(
      "127.0.0.1", port,
      items + "?bbox=0,0,1,1&bbox-crs=http://www.opengis.net/def/crs/EPSG/0/2959", admin);
  EXPECT_EQ(nlohmann::json::parse(missed.body)["numberReturned"], 0) << missed.body;
  // The map's collection links to it; a map without one has none; tokens apply.
  const test::HttpAnswer map = test::HttpGet("127.0.0.1", port, "/ogc/collections/plot", admin);
  EXPECT_NE(map.body.find("/ogc/collections/plot:boundary\""), std::string::npos) << map.body;
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, items + "/1", admin).status, 200);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, items + "/2", admin).status, 404);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, items + "?colour=red", admin).status, 400);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, "/ogc/collections/other:boundary", admin).status, 404);
  EXPECT_EQ(test::HttpGet("127.0.0.1", port, items, other_reader).status, 403);
}

TEST_F(DaemonHttpTest, OgcItemsPageAHugeMapInBoundedMemory) {
  WriteHugeMap();
  const int port = ServeWithPage();
  ASSERT_GT(port, 0);
  const int pid = std::stoi(ReadFile(dir_ / "pid"));
  const int64_t before = RssMib(pid);
  std::string next = "/ogc/collections/huge/items?limit=10000";
  int64_t seen = 0, last_id = 0;
  int pages = 0;
  while (!next.empty()) {
    const test::HttpAnswer answer = test::HttpGet("127.0.0.1", port, next);
    ASSERT_EQ(answer.status, 200) << next << ": " << answer.body;
    const nlohmann::json page = nlohmann::json::parse(answer.body);
    for (const nlohmann::json& feature : page["features"]) {
      ASSERT_GT(feature["id"].get<int64_t>(), last_id);  // increasing: nothing twice
      last_id = feature["id"];
      ++seen;
    }
    next.clear();
    for (const nlohmann::json& link : page["links"]) {  // the next page, as a client follows it
      const std::string href = link["href"];
      if (link["rel"] == "next") next = href.substr(href.find("/ogc"));
    }
    ++pages;
  }
  EXPECT_EQ(seen, kHugeMapTrees);
  EXPECT_EQ(pages, kHugeMapTrees / 10'000 + 1);
  const int64_t growth = RssMib(pid) - before;
  RecordProperty("rss_growth_mib", std::to_string(growth));
  EXPECT_LE(growth, kRssGrowthBoundMib) << "RSS " << before << " MiB before, +" << growth;
}

}  // namespace
}  // namespace forestmap
