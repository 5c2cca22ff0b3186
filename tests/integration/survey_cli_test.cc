// Survey teams' workflow through the built `forestmap` binary against a real in-process
// server: PRF025's field inventory uploaded as delivered, exported to GeoPackage / GeoJSON /
// shapefile and checked with GDAL's own `ogrinfo`, read back, and every input error refused
// with one message naming file and field, leaving nothing behind.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>

#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/cli_run.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;

const std::string kPlot = std::string(FORESTMAP_SHARED_DATA) + "/survey_vs_lidar/PRF025/";
const std::string kFieldColumns = "--columns x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree";
// PRF025_Field.csv's columns other than the four mapped ones: each must reach the export, LI and
// LO too, which are NA in all 62 rows (null fields), with the type of its values (QGIS compares
// numbers as numbers: Ht > 5).
const std::pair<const char*, const char*> kFieldAttributes[] = {
    {"Plot", "String"},   {"Spp", "Integer64"}, {"Status", "String"}, {"Origin", "String"},
    {"Dist", "Real"},     {"Azim", "Real"},     {"DbhHt", "Real"},    {"Ht", "Real"},
    {"LI", "String"},     {"LO", "String"},     {"BT", "String"},     {"Plotsize", "String"},
    {"Dbh_meas", "Real"}, {"Field_X", "Real"},  {"Field_Y", "Real"},  {"Easting", "Real"},
    {"Northing", "Real"}};

using Result = testing_util::CliResult;
using testing_util::ReadWholeFile;

class SurveyCliTest : public ::testing::Test {
 protected:
  SurveyCliTest()
      : store_(":memory:"),
        service_(store_, {}),
        runner_("127.0.0.1:0", service_),
        client_(runner_.address()) {}

  void SetUp() override {
    if (!fs::exists(kPlot + "PRF025_Field.csv")) GTEST_SKIP() << "no " << kPlot;
    dir_ = testing_util::FreshTestFolder("forestmap_survey_test");
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  // Runs a shell command line, capturing its output.
  Result Shell(const std::string& command) { return testing_util::RunCapturing(command, dir_); }
  Result Cli(const std::string& args) {
    return Shell("'" FORESTMAP_CLI_PATH "' --server " + runner_.address() + " " + args);
  }
  Result Lab(const std::string& args) { return Shell("'" FORESTMAP_LAB_PATH "' " + args); }
  Result CreateField(const std::string& name, const std::string& extra) {
    return Cli("map create " + name + " --trees '" + kPlot + "PRF025_Field.csv' " + kFieldColumns +
               " " + extra);
  }

  storage::SqliteMapStore store_;
  server::ForestMapService service_;
  server::ServerRunner runner_;
  client::ForestMapClient client_;
  fs::path dir_;
};

TEST_F(SurveyCliTest, FieldInventoryUploadsAndExportsToGeoPackageWithCrsAndAttributes) {
  const Result created = CreateField("prf025", "--dbh-unit cm --crs EPSG:2959");
  ASSERT_EQ(created.exit_code, 0) << created.err;
  EXPECT_EQ(client_.GetMap("prf025").tree_count(), 62);
  const std::string gpkg = (dir_ / "prf025.gpkg").string();
  const Result exported = Cli("map export prf025 --out '" + gpkg + "'");
  ASSERT_EQ(exported.exit_code, 0) << exported.err;

  const Result info = Shell("ogrinfo -so -al '" + gpkg + "'");
  ASSERT_EQ(info.exit_code, 0) << info.err << " (is gdal-bin installed?)";
  EXPECT_NE(info.out.find("Feature Count: 62"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("Geometry: Point"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("ID[\"EPSG\",2959]]"), std::string::npos) << info.out;
  for (const char* field : {"id", "x", "y", "dbh"}) {
    EXPECT_NE(info.out.find(std::string("\n") + field + ": "), std::string::npos) << field;
  }
  for (const auto& [attribute, type] : kFieldAttributes) {
    EXPECT_NE(info.out.find(std::string("\n") + attribute + ": " + type + " "), std::string::npos)
        << attribute << " (" << type << ") missing from\n"
        << info.out;
  }
  // A value: tree 1 has DBH 14.9 cm and species code 41.
  const Result tree1 = Shell("ogrinfo -al -where 'id = 1' '" + gpkg + "'");
  EXPECT_NE(tree1.out.find("dbh (Real) = 0.149"), std::string::npos) << tree1.out;
  EXPECT_NE(tree1.out.find("Spp (Integer64) = 41"), std::string::npos) << tree1.out;
  EXPECT_NE(tree1.out.find("Ht (Real) = 16.8"), std::string::npos) << tree1.out;
  for (const char* unknown : {"LI", "LO", "BT"}) {  // NA in the file: null fields
    EXPECT_NE(tree1.out.find(std::string(unknown) + " (String) = (null)"), std::string::npos)
        << unknown << " in\n"
        << tree1.out;
  }
}

TEST_F(SurveyCliTest, GeoJsonShapefileAndCsvRoundTripWithTheirCrsAndNullFields) {
  ASSERT_EQ(CreateField("prf025", "--dbh-unit cm --crs EPSG:2959").exit_code, 0);
  for (const std::string name : {"trees.geojson", "trees.shp", "table.csv"}) {
    const std::string path = (dir_ / name).string();
    const Result exported = Cli("map export prf025 --out '" + path + "'");
    ASSERT_EQ(exported.exit_code, 0) << exported.err;
    EXPECT_EQ(exported.err.find("4.29e-16 (and any like it) is rounded") != std::string::npos,
              name == "trees.shp")
        << exported.err;
    const std::string copy = "copy_" + fs::path(name).extension().string().substr(1);
    const Result created = Cli("map create " + copy + " --trees '" + path + "'");
    ASSERT_EQ(created.exit_code, 0) << created.err;
    const v1::Map map = client_.GetMap(copy);
    EXPECT_EQ(map.tree_count(), 62) << name;
    EXPECT_EQ(map.crs_epsg(), 2959) << name << ": " << map.crs();
    const auto original = client_.ExportTrees("prf025").trees;
    const auto read_back = client_.ExportTrees(copy).trees;
    ASSERT_EQ(read_back.size(), original.size());
    for (size_t i = 0; i < original.size(); ++i) {
      EXPECT_EQ(read_back[i].id, original[i].id);
      EXPECT_NEAR(read_back[i].x, original[i].x, 1e-6);
      EXPECT_NEAR(read_back[i].y, original[i].y, 1e-6);
      EXPECT_NEAR(read_back[i].dbh.value_or(-1), original[i].dbh.value_or(-1), 1e-9);
      // A shapefile keeps 15 decimals: the survey's 4.29e-16 (a cosine's remainder) reads back 0.
      auto expected = original[i].attributes;
      if (name == "trees.shp" && expected["Field_Y"] == "4.29e-16") expected["Field_Y"] = "0";
      EXPECT_EQ(read_back[i].attributes, expected) << name;
      EXPECT_EQ(read_back[i].null_attributes, original[i].null_attributes) << name;
    }
    EXPECT_EQ(original[0].null_attributes.count("LI"), 1u);
  }
}

// Files in degrees or feet (QGIS writes GeoJSON in WGS 84, as RFC 7946 says) are refused with
// the --to-crs that takes them, reprojected with it, and moved into an existing map's CRS by
// `map upload`.
TEST_F(SurveyCliTest, TreesInDegreesOrFeetAreReprojectedIntoMetres) {
  ASSERT_EQ(CreateField("prf025", "--dbh-unit cm --crs EPSG:2959").exit_code, 0);
  const std::string gpkg = (dir_ / "prf025.gpkg").string();
  ASSERT_EQ(Cli("map export prf025 --out '" + gpkg + "'").exit_code, 0);
  const std::string degrees = (dir_ / "wgs84.geojson").string();
  const std::string feet = (dir_ / "feet.geojson").string();
  ASSERT_EQ(
      Shell("ogr2ogr -f GeoJSON -lco RFC7946=YES -t_srs EPSG:4326 '" + degrees + "' '" + gpkg + "'")
          .exit_code,
      0);
  ASSERT_EQ(Shell("ogr2ogr -f GeoJSON -t_srs EPSG:2263 '" + feet + "' '" + gpkg + "'").exit_code,
            0);

  const Result refused = Cli("map create wgs --trees '" + degrees + "'");
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("wgs84.geojson: its CRS EPSG:4326 (WGS 84) cannot be a map's: it is "
                             "geographic"),
            std::string::npos)
      << refused.err;
  EXPECT_NE(refused.err.find("--to-crs utm (here EPSG:32618)"), std::string::npos) << refused.err;

  const auto original = client_.ExportTrees("prf025").trees;
  const auto expect_original = [&](const std::string& map, double tolerance) {
    const auto trees = client_.ExportTrees(map).trees;
    ASSERT_EQ(trees.size(), original.size()) << map;
    for (size_t i = 0; i < trees.size(); ++i) {
      EXPECT_EQ(trees[i].id, original[i].id) << map;
      EXPECT_NEAR(trees[i].x, original[i].x, tolerance) << map << " tree " << *trees[i].id;
      EXPECT_NEAR(trees[i].y, original[i].y, tolerance) << map << " tree " << *trees[i].id;
      EXPECT_EQ(trees[i].attributes, original[i].attributes) << map;
    }
  };
  constexpr double kRfc7946Metres = 0.02;  // RFC 7946 GeoJSON keeps 7 decimals of a degree
  const Result back = Cli("map create back --trees '" + degrees + "' --to-crs EPSG:2959");
  ASSERT_EQ(back.exit_code, 0) << back.err;
  EXPECT_NE(back.err.find("62 trees reprojected from EPSG:4326 (WGS 84) to EPSG:2959"),
            std::string::npos)
      << back.err;
  expect_original("back", kRfc7946Metres);
  ASSERT_EQ(Cli("map create zone --trees '" + degrees + "' --to-crs utm").exit_code, 0);
  EXPECT_EQ(client_.GetMap("zone").crs_epsg(), 32618);

  // Degrees in a CSV without a CRS: the trees are centimetres apart, which says so.
  const fs::path lon_lat = dir_ / "lon_lat.csv";
  std::ofstream table(lon_lat);
  table << "x,y\n";
  for (int i = 0; i < 20; ++i)
    table << -75.25 + i % 5 * 3e-5 << ',' << 46.03 + i / 5 * 3e-5 << '\n';
  table.close();
  const Result warned = Cli("map create lonlat --trees '" + lon_lat.string() + "'");
  EXPECT_EQ(warned.exit_code, 0) << warned.err;
  EXPECT_NE(warned.err.find("are x and y metres? (for degrees: --crs EPSG:4326 --to-crs utm)"),
            std::string::npos)
      << warned.err;
  EXPECT_EQ(CreateField("metres", "--dbh-unit cm").err.find("are x and y metres"),
            std::string::npos);

  // A --crs that contradicts the file's own is refused; trees outside their CRS's area warned.
  const Result relabel = Cli("map create relabel --trees '" + feet + "' --crs EPSG:2959");
  EXPECT_EQ(relabel.exit_code, 1);
  EXPECT_NE(relabel.err.find("feet.geojson declares its CRS, EPSG:2263"), std::string::npos)
      << relabel.err;
  const Result europe = CreateField("europe", "--dbh-unit cm --crs EPSG:3067");
  EXPECT_EQ(europe.exit_code, 0) << europe.err;
  EXPECT_NE(europe.err.find("is outside the area of use of EPSG:3067"), std::string::npos)
      << europe.err;
  EXPECT_EQ(CreateField("canada", "--dbh-unit cm --crs EPSG:2959").err.find("area of use"),
            std::string::npos);

  // Web Mercator holds metres that are not the ground's (0.69 m at 46 N): created, with a warning.
  const std::string mercator = (dir_ / "mercator.gpkg").string();
  ASSERT_EQ(Shell("ogr2ogr -t_srs EPSG:3857 '" + mercator + "' '" + gpkg + "'").exit_code, 0);
  const Result scaled = Cli("map create mercator --trees '" + mercator + "'");
  EXPECT_EQ(scaled.exit_code, 0) << scaled.err;
  EXPECT_NE(scaled.err.find("a metre of EPSG:3857 (WGS 84 / Pseudo-Mercator) is 0.69"),
            std::string::npos)
      << scaled.err;

  // compare: the map (EPSG:2959) against the same trees in degrees, both taken to UTM 18N.
  const Result compared = Cli("compare map:prf025 --reference '" + degrees + "' --json");
  ASSERT_EQ(compared.exit_code, 0) << compared.err;
  const nlohmann::json comparison = nlohmann::json::parse(compared.out);
  EXPECT_EQ(comparison["linked"], 62) << compared.out;
  EXPECT_LT(comparison["position_rmse_m"].get<double>(), kRfc7946Metres) << compared.out;

  // map upload: the feet file into a map in metres, then a replace by the GeoPackage.
  ASSERT_EQ(Cli("map create upload --crs EPSG:2959").exit_code, 0);
  const Result appended = Cli("map upload upload --trees '" + feet + "'");
  ASSERT_EQ(appended.exit_code, 0) << appended.err;
  EXPECT_NE(appended.out.find("appended to map 'upload': 62 trees uploaded, 62 trees"),
            std::string::npos)
      << appended.out;
  expect_original("upload", 1e-6);
  const Result replaced = Cli("map upload upload --replace --trees '" + gpkg + "'");
  ASSERT_EQ(replaced.exit_code, 0) << replaced.err;
  EXPECT_NE(replaced.out.find("replaced the trees of map 'upload': 62 trees uploaded, 62 trees, "
                              "version 3"),
            std::string::npos)
      << replaced.out;
  const Result twice = Cli("map upload upload --trees '" + gpkg + "'");  // the same ids again
  EXPECT_EQ(twice.exit_code, 1);
  EXPECT_NE(twice.err.find("tree id already exists in the map; the map is unchanged"),
            std::string::npos)
      << twice.err;
  EXPECT_EQ(client_.GetMap("upload").version(), 3);
  EXPECT_EQ(Cli("map upload nosuch --trees '" + gpkg + "'").exit_code, 1);
  // prf025, back, zone, lonlat, metres, europe, canada, mercator, upload
  EXPECT_EQ(client_.ListMaps().size(), 9u);
}

TEST_F(SurveyCliTest, InputErrorsNameFileAndFieldAndCreateNothing) {
  const Result unit = CreateField("a", "--crs EPSG:2959");
  EXPECT_EQ(unit.exit_code, 1);
  EXPECT_NE(unit.err.find("PRF025_Field.csv: column 'DBH'"), std::string::npos) << unit.err;
  EXPECT_NE(unit.err.find("--dbh-unit cm"), std::string::npos) << unit.err;

  const Result unmapped = Cli("map create b --trees '" + kPlot + "PRF025_Field.csv'");
  EXPECT_EQ(unmapped.exit_code, 1);
  EXPECT_NE(unmapped.err.find("PRF025_Field.csv:1: missing required column 'x'"), std::string::npos)
      << unmapped.err;

  const Result crs = CreateField("c", "--dbh-unit cm --crs 'not a crs at all'");
  EXPECT_EQ(crs.exit_code, 1);
  EXPECT_NE(crs.err.find("PRF025_Field.csv: CRS 'not a crs at all' is not one PROJ knows"),
            std::string::npos)
      << crs.err;

  const fs::path bad = dir_ / "bad.geojson";
  std::ofstream(bad) << "{\"type\": \"FeatureCollection\", \"features\": [{\"type\": ";
  const Result geojson = Cli("map create d --trees '" + bad.string() + "'");
  EXPECT_EQ(geojson.exit_code, 1);
  EXPECT_NE(geojson.err.find(bad.string() + ": not a readable geojson file"), std::string::npos)
      << geojson.err;

  const fs::path text_dbh = dir_ / "text.geojson";
  std::ofstream(text_dbh) << R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"dbh": "thick"},
     "geometry": {"type": "Point", "coordinates": [1, 2]}}]})";
  const Result field = Cli("map create e --trees '" + text_dbh.string() + "'");
  EXPECT_EQ(field.exit_code, 1);
  EXPECT_NE(field.err.find("text.geojson: feature 1: field 'dbh': 'thick' is not a number"),
            std::string::npos)
      << field.err;

  EXPECT_TRUE(client_.ListMaps().empty()) << "a refused upload left a map behind";
}

}  // namespace
}  // namespace forestmap

namespace forestmap {
namespace {

struct Link {
  std::string detected, reference;
  double distance = 0, dbh_difference = 0;
};

std::vector<Link> ReadLinks(const fs::path& path) {
  std::vector<Link> links;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream fields(line);
    for (std::string field; std::getline(fields, field, ',');) f.push_back(field);
    if (f.size() < 10) f.resize(10);
    links.push_back({f[0], f[1], std::stod(f[6]), f[9].empty() ? NAN : std::stod(f[9])});
  }
  std::sort(links.begin(), links.end(), [](const Link& a, const Link& b) {
    return std::tie(a.detected, a.reference) < std::tie(b.detected, b.reference);
  });
  return links;
}

// The LiDAR inventory moved by a rotation of `degrees` about the origin and a shift.
fs::path MovedLidar(const fs::path& dir, double degrees) {
  const auto rows = client::ReadMapTreesCsv(kPlot + "PRF025_Lidar.csv");
  const double a = degrees * M_PI / 180.0;
  const fs::path path = dir / "lidar_moved.csv";
  std::ofstream out(path);
  out.precision(12);
  out << "treeID,X,Y,DBH\n";
  for (const auto& row : rows) {
    const double x = row.x - 312000, y = row.y - 5096000;  // local, so the rotation is large
    out << *row.id << ',' << std::cos(a) * x - std::sin(a) * y + 1234.5 << ','
        << std::sin(a) * x + std::cos(a) * y - 678.9 << ',' << *row.dbh << '\n';
  }
  return path;
}

double RegisteredRotation(const std::string& err) {
  const size_t at = err.find("registered: rotation ");
  EXPECT_NE(at, std::string::npos) << err;
  return at == std::string::npos ? NAN : std::stod(err.substr(at + 21));
}

TEST_F(SurveyCliTest, CompareLidarWithFieldInventory) {
  const std::string reference = " --reference '" + kPlot +
                                "PRF025_Field.csv' --reference-columns "
                                "x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree --reference-dbh-unit cm";
  const fs::path links_csv = dir_ / "links.csv";
  const Result plain = Cli("compare '" + kPlot + "PRF025_Lidar.csv'" + reference +
                           " --json --out '" + links_csv.string() + "'");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  const nlohmann::json result = nlohmann::json::parse(plain.out);
  EXPECT_EQ(result["reference_trees"], 62);
  EXPECT_EQ(result["detected_trees"], 93);
  // The links: one-to-one, within 0.8 m, and the reported DBH RMSE is theirs.
  const std::vector<Link> links = ReadLinks(links_csv);
  EXPECT_EQ(links.size(), result["linked"].get<size_t>());
  std::set<std::string> detected, referenced;
  double squared = 0;
  int pairs = 0;
  for (const Link& link : links) {
    EXPECT_LE(link.distance, 0.8);
    EXPECT_TRUE(detected.insert(link.detected).second) << link.detected << " linked twice";
    EXPECT_TRUE(referenced.insert(link.reference).second) << link.reference << " linked twice";
    if (!std::isnan(link.dbh_difference)) {
      squared += link.dbh_difference * link.dbh_difference;
      ++pairs;
    }
  }
  EXPECT_EQ(pairs, result["dbh_pairs"].get<int>());
  EXPECT_NEAR(std::sqrt(squared / pairs), result["dbh_rmse_m"].get<double>(), 1e-4);

  // The table says the same.
  const Result table = Cli("compare '" + kPlot + "PRF025_Lidar.csv'" + reference);
  EXPECT_NE(table.out.find("linked           " + std::to_string(links.size()) + " of 62"),
            std::string::npos)
      << table.out;
  EXPECT_NE(table.out.find("DBH RMSE"), std::string::npos) << table.out;

  // --register: the original and a moved copy of the LiDAR give the same links, and the two
  // registrations differ by the rotation applied.
  const fs::path registered_csv = dir_ / "registered.csv", moved_csv = dir_ / "moved_links.csv";
  const Result registered = Cli("compare '" + kPlot + "PRF025_Lidar.csv' --register" + reference +
                                " --out '" + registered_csv.string() + "'");
  ASSERT_EQ(registered.exit_code, 0) << registered.err;
  constexpr double kRotation = 37.0;  // deg
  const Result moved = Cli("compare '" + MovedLidar(dir_, kRotation).string() + "' --register" +
                           reference + " --out '" + moved_csv.string() + "'");
  ASSERT_EQ(moved.exit_code, 0) << moved.err;
  const std::vector<Link> a = ReadLinks(registered_csv), b = ReadLinks(moved_csv);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_GE(a.size(), links.size());  // registration removes the survey's misalignment
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].detected, b[i].detected);
    EXPECT_EQ(a[i].reference, b[i].reference);
  }
  EXPECT_NEAR(RegisteredRotation(registered.err) - RegisteredRotation(moved.err), kRotation, 0.01);
}

}  // namespace
}  // namespace forestmap

namespace forestmap {
namespace {

// Measured on this scan: 181 trunks, 1 unlinked, position RMSE 0.065 m, DBH RMSE 3.8 cm,
// registered rotation 29.996 deg. The bounds leave room for detector tuning.
constexpr int kMinScanTrunks = 150;
constexpr double kMaxScanCommission = 0.05;
constexpr double kMaxScanPositionRmse = 0.10;  // m
constexpr double kMaxScanDbhRmse = 0.05;       // m
constexpr double kScanYaw = 30.0;              // deg, the simulated pose's yaw
constexpr double kMaxYawError = 0.1;           // deg

std::string Quoted(const fs::path& path) { return std::string("'") + path.string() + "'"; }

// A scan as the detections: its trunks are detected as `forestmap detect` finds them, then linked
// to the simulator's truth (sensor frame) and, with --register, to the scene's map (map frame,
// the sensor at (60, 60) turned by 30 degrees): the same trees either way.
TEST_F(SurveyCliTest, CompareScanWithItsTruthAndRegisteredWithTheMap) {
  const fs::path sim = dir_ / "sim";
  const Result simulated =
      Lab("simulate --generate 2000 --pose 60,60,3,30 --no-body --out '" + sim.string() + "'");
  ASSERT_EQ(simulated.exit_code, 0) << simulated.err;
  const std::string scan = Quoted(sim / "scan_000.pcd");
  const fs::path truth_links = dir_ / "truth_links.csv", map_links = dir_ / "map_links.csv";
  const Result truth =
      Cli("compare " + scan + " --reference '" + (sim / "scan_000_truth.csv").string() +
          "' --json --out '" + truth_links.string() + "'");
  ASSERT_EQ(truth.exit_code, 0) << truth.err;
  EXPECT_NE(truth.err.find("trunks detected in"), std::string::npos) << truth.err;
  const nlohmann::json result = nlohmann::json::parse(truth.out);
  const int detected = result["detected_trees"];
  EXPECT_GE(detected, kMinScanTrunks);
  EXPECT_LE(result["commission"].get<double>(), kMaxScanCommission) << truth.out;
  EXPECT_LE(result["position_rmse_m"].get<double>(), kMaxScanPositionRmse) << truth.out;
  EXPECT_LE(result["dbh_rmse_m"].get<double>(), kMaxScanDbhRmse) << truth.out;

  const Result registered =
      Cli("compare " + scan + " --register --reference '" + (sim / "map.csv").string() +
          "' --out '" + map_links.string() + "'");
  ASSERT_EQ(registered.exit_code, 0) << registered.err;
  EXPECT_NEAR(RegisteredRotation(registered.err), kScanYaw, kMaxYawError) << registered.err;
  const std::vector<Link> a = ReadLinks(truth_links), b = ReadLinks(map_links);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].detected, b[i].detected);
    EXPECT_EQ(a[i].reference, b[i].reference);  // truth tree_id = the map's id
  }

  const Result laz = Cli("compare '" + (dir_ / "scan.laz").string() + "' --reference '" +
                         (sim / "map.csv").string() + "'");
  EXPECT_EQ(laz.exit_code, 1);
  EXPECT_NE(laz.err.find("scan.laz"), std::string::npos) << laz.err;
}

}  // namespace
}  // namespace forestmap
