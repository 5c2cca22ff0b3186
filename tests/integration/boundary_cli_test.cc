// A survey boundary through the built `forestmap` binary against a real in-process server:
// given to `map create` and `map upload` as GeoJSON, GeoPackage or a CSV ring, kept by an upload
// without one, put into the map's CRS, exported beside the trees (checked with GDAL's own
// `ogrinfo`), and every bad boundary refused with the map unchanged.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "client/io/boundary_io.h"
#include "client/lib/forestmap_client.h"
#include "geo/crs.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/cli_run.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using Result = testing_util::CliResult;

class BoundaryCliTest : public ::testing::Test {
 protected:
  BoundaryCliTest()
      : store_(":memory:"),
        service_(store_, {}),
        runner_("127.0.0.1:0", service_),
        client_(runner_.address()) {}

  void SetUp() override { dir_ = testing_util::FreshTestFolder("forestmap_boundary_cli_test"); }
  void TearDown() override { fs::remove_all(dir_); }

  Result Shell(const std::string& command) { return testing_util::RunCapturing(command, dir_); }
  Result Cli(const std::string& args) {
    return Shell("'" FORESTMAP_CLI_PATH "' --server " + runner_.address() + " " + args);
  }
  std::string Write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }
  // Trees on a 5 m grid inside [x0, x0 + 40] x [y0, y0 + 40].
  std::string Trees(const std::string& name, double x0, double y0, int first_id) {
    std::string text = "id,x,y,dbh\n";
    int id = first_id;
    for (int i = 0; i < 8; ++i) {
      for (int j = 0; j < 8; ++j) {
        text += std::to_string(id++) + "," + std::to_string(x0 + 5 * i + 0.3 * j) + "," +
                std::to_string(y0 + 5 * j) + ",0.25\n";
      }
    }
    return Write(name, text);
  }

  storage::SqliteMapStore store_;
  server::ForestMapService service_;
  server::ServerRunner runner_;
  client::ForestMapClient client_;
  fs::path dir_;
};

// A local grid: `"crs": null` says so (without it, coordinates this small read as RFC 7946's
// longitudes and latitudes).
const char* kSquareWithHole = R"({"type": "FeatureCollection", "crs": null,
  "features": [{"type": "Feature",
  "properties": {}, "geometry": {"type": "Polygon", "coordinates": [
  [[-5,-5],[50,-5],[50,50],[-5,50],[-5,-5]], [[20,20],[20,24],[24,24],[24,20],[20,20]]]}}]})";

TEST_F(BoundaryCliTest, CreateUploadKeepReplaceAndExportBesideTheTrees) {
  const std::string trees = Trees("trees.csv", 0, 0, 1);
  const std::string boundary = Write("boundary.geojson", kSquareWithHole);
  const Result created =
      Cli("map create plot --trees '" + trees + "' --boundary '" + boundary + "'");
  ASSERT_EQ(created.exit_code, 0) << created.err;
  client::ExportedTrees exported = client_.ExportTrees("plot");
  ASSERT_EQ(exported.boundary.size(), 1u);
  EXPECT_EQ(exported.boundary[0].outer, (algorithms::Ring{{-5, -5}, {50, -5}, {50, 50}, {-5, 50}}));
  ASSERT_EQ(exported.boundary[0].holes.size(), 1u);
  const int64_t created_version = client_.GetMap("plot").version();

  // More trees without --boundary: the map keeps its boundary.
  const Result appended = Cli("map upload plot --trees '" + Trees("more.csv", 0, 100, 100) + "'");
  ASSERT_EQ(appended.exit_code, 0) << appended.err;
  exported = client_.ExportTrees("plot");
  EXPECT_EQ(exported.map_version, created_version + 1);
  EXPECT_EQ(exported.boundary.size(), 1u);

  // A boundary alone, as a CSV ring: a new version with the same trees.
  const std::string ring = Write("ring.csv", "x,y\n-5,-5\n50,-5\n50,150\n-5,150\n-5,-5\n");
  const Result bounded = Cli("map upload plot --boundary '" + ring + "'");
  ASSERT_EQ(bounded.exit_code, 0) << bounded.err;
  EXPECT_NE(bounded.out.find("survey boundary of 1 polygons"), std::string::npos) << bounded.out;
  exported = client_.ExportTrees("plot");
  EXPECT_EQ(exported.map_version, created_version + 2);
  EXPECT_EQ(exported.trees.size(), 128u);
  ASSERT_EQ(exported.boundary.size(), 1u);
  EXPECT_EQ(exported.boundary[0].outer[2], Eigen::Vector2d(50, 150));
  EXPECT_TRUE(exported.boundary[0].holes.empty());

  // GeoPackage: a second layer `boundary`, read back by GDAL's own ogrinfo.
  const std::string gpkg = (dir_ / "plot.gpkg").string();
  const Result to_gpkg = Cli("map export plot --out '" + gpkg + "'");
  ASSERT_EQ(to_gpkg.exit_code, 0) << to_gpkg.err;
  EXPECT_NE(to_gpkg.err.find("layer 'boundary'"), std::string::npos) << to_gpkg.err;
  const Result layers = Shell("ogrinfo -so '" + gpkg + "'");
  ASSERT_EQ(layers.exit_code, 0) << layers.err << " (is gdal-bin installed?)";
  EXPECT_NE(layers.out.find("plot (Point)"), std::string::npos) << layers.out;
  EXPECT_NE(layers.out.find("boundary (Polygon)"), std::string::npos) << layers.out;
  const Result polygon = Shell("ogrinfo -al -q '" + gpkg + "' boundary");
  EXPECT_NE(polygon.out.find("POLYGON ((-5 -5,50 -5,50 150,-5 150,-5 -5))"), std::string::npos)
      << polygon.out;
  // GeoJSON holds one layer a file: the boundary goes to plot.boundary.geojson beside it.
  const Result to_json = Cli("map export plot --out '" + (dir_ / "plot.geojson").string() + "'");
  ASSERT_EQ(to_json.exit_code, 0) << to_json.err;
  const Result sibling =
      Shell("ogrinfo -al -q '" + (dir_ / "plot.boundary.geojson").string() + "'");
  EXPECT_NE(sibling.out.find("POLYGON ((-5 -5,50 -5,50 150,-5 150,-5 -5))"), std::string::npos)
      << sibling.out << sibling.err;
  // CSV has no place for it: said, the trees written.
  const Result to_csv = Cli("map export plot --out '" + (dir_ / "plot.csv").string() + "'");
  ASSERT_EQ(to_csv.exit_code, 0) << to_csv.err;
  EXPECT_NE(to_csv.err.find("a CSV cannot hold"), std::string::npos) << to_csv.err;
  // The picture draws it.
  const Result plotted = Cli("plot plot --out '" + (dir_ / "plot.svg").string() + "'");
  ASSERT_EQ(plotted.exit_code, 0) << plotted.err;
  EXPECT_NE(testing_util::ReadWholeFile(dir_ / "plot.svg").find("stroke-dasharray"),
            std::string::npos);
}

TEST_F(BoundaryCliTest, ABoundaryInAnotherCrsIsReprojectedIntoTheMapsOne) {
  // Map in UTM zone 18N; the boundary drawn in zone 17N (the same ground, other numbers).
  ASSERT_EQ(Cli("map create utm --crs EPSG:32618").exit_code, 0);
  algorithms::Polygon polygon;
  polygon.outer = {{1000000, 5000000}, {1000400, 5000000}, {1000400, 5000300}};
  const std::string gpkg = (dir_ / "zone17.gpkg").string();
  client::WriteGeoBoundary(gpkg, client::TreeFormat::kGeoPackage, {polygon}, "EPSG:32617");
  const Result uploaded = Cli("map upload utm --boundary '" + gpkg + "'");
  ASSERT_EQ(uploaded.exit_code, 0) << uploaded.err;
  const client::ExportedTrees exported = client_.ExportTrees("utm");
  ASSERT_EQ(exported.boundary.size(), 1u);
  const geo::Reprojection move("EPSG:32617", "EPSG:32618");
  for (size_t i = 0; i < polygon.outer.size(); ++i) {
    double x = polygon.outer[i].x(), y = polygon.outer[i].y(), z = 0;
    move.Apply(x, y, z);
    EXPECT_NEAR(exported.boundary[0].outer[i].x(), x, 1e-6) << i;
    EXPECT_NEAR(exported.boundary[0].outer[i].y(), y, 1e-6) << i;
    EXPECT_GT(std::abs(x - polygon.outer[i].x()), 1000.0);  // it did move
  }
}

TEST_F(BoundaryCliTest, BadBoundariesAreRefusedAndTheMapIsUnchanged) {
  ASSERT_EQ(Cli("map create plot --trees '" + Trees("trees.csv", 0, 0, 1) + "'").exit_code, 0);
  const int64_t version = client_.GetMap("plot").version();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {Write("line.csv", "x,y\n0,0\n1,1\n2,2\n"), "encloses no area"},
      {Write("bowtie.csv", "x,y\n0,0\n10,10\n10,0\n0,20\n"), "is not valid"},
      {Write("points.geojson", R"({"type": "FeatureCollection", "features": [{"type": "Feature",
         "properties": {}, "geometry": {"type": "Point", "coordinates": [1, 2]}}]})"),
       "not a polygon"},
      // Degrees, and the map has no CRS to take them to.
      {Write("wgs84.geojson", R"({"type": "FeatureCollection", "features": [{"type": "Feature",
         "properties": {}, "geometry": {"type": "Polygon", "coordinates":
         [[[-75.1, 45.1], [-75.0, 45.1], [-75.0, 45.2], [-75.1, 45.1]]]}}]})"),
       "has no CRS to reproject it into"},
      {(dir_ / "missing.gpkg").string(), "no such file"},
  };
  for (const auto& [path, fragment] : cases) {
    const Result refused = Cli("map upload plot --boundary '" + path + "'");
    EXPECT_NE(refused.exit_code, 0) << path;
    EXPECT_NE(refused.err.find(fragment), std::string::npos) << path << ": " << refused.err;
  }
  const Result both_missing = Cli("map upload plot");
  EXPECT_NE(both_missing.err.find("give --trees FILE, --boundary FILE or both"), std::string::npos)
      << both_missing.err;
  EXPECT_EQ(client_.GetMap("plot").version(), version);
  EXPECT_TRUE(client_.ExportTrees("plot").boundary.empty());
}

}  // namespace
}  // namespace forestmap
