// Survey teams' workflow (issue 14) through the built `forestmap` binary against a real in-process
// server: PRF025's field inventory uploaded as delivered, exported to GeoPackage / GeoJSON /
// shapefile and checked with GDAL's own `ogrinfo`, read back, and every input error refused
// with one message naming file and field, leaving nothing behind.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "client/forestmap_client.h"
#include "server/server.h"
#include "server/service.h"
#include "storage/sqlite_map_store.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;

const std::string kPlot = std::string(FORESTMAP_SHARED_DATA) + "/survey_vs_lidar/PRF025/";
const std::string kFieldColumns = "--columns x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree";
// PRF025_Field.csv's columns other than the four mapped ones: each must reach the export. (LI and
// LO are NA in all 62 rows: an unknown value is an absent attribute, so they have no field.)
const char* kFieldAttributes[] = {"Plot",     "Spp",     "Status",  "Origin",  "Dist",
                                  "Azim",     "DbhHt",   "Ht",      "BT",      "Plotsize",
                                  "Dbh_meas", "Field_X", "Field_Y", "Easting", "Northing"};

struct Result {
  int exit_code = -1;
  std::string out, err;
};

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class SurveyCliTest : public ::testing::Test {
 protected:
  SurveyCliTest()
      : store_(":memory:"),
        service_(store_, {}),
        runner_("127.0.0.1:0", service_),
        client_(runner_.address()) {}

  void SetUp() override {
    if (!fs::exists(kPlot + "PRF025_Field.csv")) GTEST_SKIP() << "no " << kPlot;
    dir_ = fs::temp_directory_path() /
           ("forestmap_survey_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  // Runs a shell command line, capturing its output.
  Result Shell(const std::string& command) {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const int status =
        std::system((command + " >'" + out.string() + "' 2>'" + err.string() + "'").c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadFile(out), ReadFile(err)};
  }
  Result Cli(const std::string& args) {
    return Shell("'" FORESTMAP_CLI_PATH "' --server " + runner_.address() + " " + args);
  }
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
  for (const char* attribute : kFieldAttributes) {
    EXPECT_NE(info.out.find(std::string("\n") + attribute + ": String"), std::string::npos)
        << attribute << " missing from\n"
        << info.out;
  }
  // A value: tree 1 has DBH 14.9 cm and species code 41.
  const Result tree1 = Shell("ogrinfo -al -where 'id = 1' '" + gpkg + "'");
  EXPECT_NE(tree1.out.find("dbh (Real) = 0.149"), std::string::npos) << tree1.out;
  EXPECT_NE(tree1.out.find("Spp (String) = 41"), std::string::npos) << tree1.out;
}

TEST_F(SurveyCliTest, GeoJsonAndShapefileRoundTripWithTheirCrs) {
  ASSERT_EQ(CreateField("prf025", "--dbh-unit cm --crs EPSG:2959").exit_code, 0);
  for (const std::string name : {"trees.geojson", "trees.shp"}) {
    const std::string path = (dir_ / name).string();
    const Result exported = Cli("map export prf025 --out '" + path + "'");
    ASSERT_EQ(exported.exit_code, 0) << exported.err;
    const std::string copy = "copy" + std::to_string(name.size());
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
    }
  }
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
  EXPECT_NE(crs.err.find("INVALID_ARGUMENT: crs \"not a crs at all\""), std::string::npos)
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
