// Survey boundaries from files without a server: GeoJSON and GeoPackage polygons (holes,
// MultiPolygons, the layer's CRS), CSV rings, what the writer writes reading back, and every
// malformed boundary refused with a message naming the file and what is wrong.

#include "client/io/boundary_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "client/io/csv_reader.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;
using algorithms::Polygon;
using algorithms::Ring;

class BoundaryIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("forestmap_boundary_io_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }
  // The CsvError message of reading `path`, or "" when it reads.
  static std::string ErrorOf(const std::string& path) {
    try {
      ReadBoundaryFile(path);
    } catch (const CsvError& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

std::string Feature(const std::string& geometry) {
  return R"({"type": "Feature", "properties": {}, "geometry": )" + geometry + "}";
}

std::string Collection(const std::string& features, const std::string& crs = "") {
  return R"({"type": "FeatureCollection", )" + crs + R"("features": [)" + features + "]}";
}

const char* kSquareWithHole =
    R"({"type": "Polygon", "coordinates": [[[0,0],[100,0],[100,100],[0,100],[0,0]],)"
    R"([[40,40],[40,50],[50,50],[50,40],[40,40]]]})";

TEST_F(BoundaryIoTest, GeoJsonPolygonWithAHoleAndAMultiPolygon) {
  const std::string multi =
      R"({"type": "MultiPolygon", "coordinates": [[[[200,0],[300,0],[250,80],[200,0]]],)"
      R"([[[400,0],[500,0],[500,50],[400,50],[400,0]]]]})";
  const std::string path =
      Write("b.geojson", Collection(Feature(kSquareWithHole) + "," + Feature(multi),
                                    R"("crs": {"type": "name", "properties": {"name": )"
                                    R"("urn:ogc:def:crs:EPSG::2959"}}, )"));
  const BoundaryFile file = ReadBoundaryFile(path);
  ASSERT_EQ(file.polygons.size(), 3u);
  EXPECT_EQ(file.polygons[0].outer.size(), 4u);  // the repeated closing vertex dropped
  ASSERT_EQ(file.polygons[0].holes.size(), 1u);
  EXPECT_EQ(file.polygons[0].holes[0][2], Eigen::Vector2d(50, 50));
  EXPECT_EQ(file.polygons[1].outer.size(), 3u);
  EXPECT_EQ(file.polygons[2].outer[2], Eigen::Vector2d(500, 50));
  EXPECT_NE(file.crs_wkt.find("2959"), std::string::npos) << file.crs_wkt;
}

TEST_F(BoundaryIoTest, GeoJsonInALocalGridHasNoCrs) {
  // No crs member: RFC 7946's WGS 84, which coordinates in metres cannot be.
  const std::string path = Write("b.geojson", Collection(Feature(kSquareWithHole)));
  EXPECT_EQ(ReadBoundaryFile(path).crs_wkt, "");
  // "crs": null says so even for coordinates that could be degrees; without it they are.
  const std::string small =
      R"({"type": "Polygon", "coordinates": [[[0,0],[10,0],[10,10],[0,10],[0,0]]]})";
  EXPECT_EQ(
      ReadBoundaryFile(Write("n.geojson", Collection(Feature(small), R"("crs": null, )"))).crs_wkt,
      "");
  EXPECT_NE(ReadBoundaryFile(Write("w.geojson", Collection(Feature(small)))).crs_wkt, "");
}

TEST_F(BoundaryIoTest, GeoPackageWrittenAndReadBackBesideOtherLayers) {
  Polygon polygon;
  polygon.outer = {{0.5, 0.25}, {100.125, 0}, {100, 100}, {0, 100}};
  polygon.holes = {{{40, 40}, {40, 50}, {50, 50}, {50, 40}}};
  Polygon second;
  second.outer = {{200, 0}, {300, 0}, {250, 80}};
  const std::string path = (dir_ / "m.gpkg").string();
  WriteGeoTrees(path, TreeFormat::kGeoPackage, {MapTreeRow{}}, "EPSG:2959", "trees");
  WriteGeoBoundary(path, TreeFormat::kGeoPackage, {polygon, second}, "EPSG:2959", "boundary");
  // Two layers: the boundary is found as the only one with polygons, or by name.
  for (const std::string layer : {"", "boundary"}) {
    const BoundaryFile file = ReadBoundaryFile(path, layer);
    ASSERT_EQ(file.polygons.size(), 2u);
    EXPECT_EQ(file.polygons[0].outer, polygon.outer);
    EXPECT_EQ(file.polygons[0].holes, polygon.holes);
    EXPECT_EQ(file.polygons[1].outer, second.outer);
    EXPECT_NE(file.crs_wkt.find("2959"), std::string::npos);
  }
  EXPECT_NE(ReadGeoTrees(path, TreeFileOptions{}).rows.size(), 0u);  // the trees stay
}

TEST_F(BoundaryIoTest, CsvRingClosedOrNot) {
  const std::string open = Write("open.csv", "x,y\n0,0\n10,0\n10,10\n0,10\n");
  const std::string closed = Write("closed.csv", "X;Y\n0;0\n10;0\n10;10\n0;10\n0;0\n");
  for (const std::string& path : {open, closed}) {
    const BoundaryFile file = ReadBoundaryFile(path);
    ASSERT_EQ(file.polygons.size(), 1u) << path;
    EXPECT_EQ(file.polygons[0].outer, (Ring{{0, 0}, {10, 0}, {10, 10}, {0, 10}})) << path;
    EXPECT_TRUE(file.polygons[0].holes.empty());
    EXPECT_EQ(file.crs_wkt, "");
  }
}

TEST_F(BoundaryIoTest, MalformedBoundariesAreRefusedSayingWhy) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {Write("no_x.csv", "a,y\n0,0\n1,0\n1,1\n"), "needs columns x and y"},
      {Write("text.csv", "x,y\n0,0\n1,zero\n1,1\n"), "'zero' is not a number"},
      {Write("nan.csv", "x,y\n0,0\n1,nan\n1,1\n"), "a vertex is not finite"},
      {Write("two.csv", "x,y\n0,0\n1,0\n1,0\n0,0\n"), "2 distinct vertices"},
      {Write("line.csv", "x,y\n0,0\n1,1\n2,2\n"), "encloses no area"},
      {Write("bowtie.csv", "x,y\n0,0\n10,10\n10,0\n0,20\n"), "is not valid"},
      {Write("open.geojson", Collection(Feature(R"({"type": "Polygon", "coordinates": )"
                                                R"([[[0,0],[10,0],[10,10],[0,10]]]})"))),
       "is not closed"},
      {Write("point.geojson", Collection(Feature(R"({"type": "Point", "coordinates": [1,2]})"))),
       "feature 1: a Point, not a polygon"},
      {Write("hole_outside.geojson", Collection(Feature(R"({"type": "Polygon", "coordinates": )"
                                                        R"([[[0,0],[10,0],[10,10],[0,10],[0,0]],)"
                                                        R"([[20,20],[20,30],[30,30],[20,20]]]})"))),
       "is not valid"},
      {Write("empty.geojson", Collection("")), "no polygon"},
      {(dir_ / "missing.gpkg").string(), "no such file"},
  };
  for (const auto& [path, fragment] : cases) {
    const std::string error = ErrorOf(path);
    EXPECT_NE(error.find(fragment), std::string::npos) << path << ": " << error;
    EXPECT_NE(error.find(fs::path(path).filename().string()), std::string::npos) << error;
  }
}

TEST_F(BoundaryIoTest, AtMostMaxVertices) {
  std::string text = "x,y\n";
  for (size_t i = 0; i <= kMaxBoundaryVertices; ++i) {
    const double angle = 2 * M_PI * static_cast<double>(i) / (kMaxBoundaryVertices + 1);
    text += std::to_string(1000 * std::cos(angle)) + "," + std::to_string(1000 * std::sin(angle)) +
            "\n";
  }
  EXPECT_NE(ErrorOf(Write("huge.csv", text)).find("more than 100000 vertices"), std::string::npos);
}

}  // namespace
}  // namespace forestmap::client
