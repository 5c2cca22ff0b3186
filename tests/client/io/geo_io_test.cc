// GIS files through GDAL without a server: every attribute text reads back as written whatever
// type its field gets, GeoPackage layers are added beside others, and reading picks the layer.

#include "client/io/geo_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "client/io/csv_reader.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;

class GeoIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("forestmap_geo_io_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

// Texts that look like numbers but would not read back as written as one ("007", "14.90",
// "1e5"), integers beyond 64 bits, and numbers that would.
std::vector<MapTreeRow> TrickyRows() {
  const std::vector<std::vector<std::string>> columns = {
      {"62", "6", "-4"},                             // integers
      {"16.8", "6", "0.1"},                          // reals (6 reads back as 6)
      {"007", "010", "1"},                           // leading zeros: text
      {"14.90", "1e5", "2"},                         // other spellings: text
      {"12345678901234567890", "1", "2"},            // beyond int64: text
      {"0.30000000000000004", "1e-20", "123456.5"},  // 17 digits; tiny (text in a shapefile)
  };
  std::vector<MapTreeRow> rows(3);
  for (size_t i = 0; i < rows.size(); ++i) {
    rows[i].id = static_cast<int64_t>(i + 1);
    rows[i].x = 10.0 * static_cast<double>(i);
    rows[i].y = 100 + static_cast<double>(i);
    for (size_t c = 0; c < columns.size(); ++c) {
      std::string name = "a";  // appended: GCC 12 -Wrestrict misfires on "a" + std::string
      name += std::to_string(c);
      rows[i].attributes[name] = columns[c][i];
    }
  }
  rows[2].attributes.erase("a1");
  rows[2].null_attributes.insert("a1");
  return rows;
}

TEST_F(GeoIoTest, EveryAttributeReadsBackAsWrittenInEveryFormat) {
  const std::vector<MapTreeRow> rows = TrickyRows();
  for (const auto& [name, format] :
       std::vector<std::pair<std::string, TreeFormat>>{{"t.gpkg", TreeFormat::kGeoPackage},
                                                       {"t.geojson", TreeFormat::kGeoJson},
                                                       {"t.shp", TreeFormat::kShapefile}}) {
    EXPECT_TRUE(WriteGeoTrees(Path(name), format, rows, "EPSG:2959", "plot").empty()) << name;
    const GeoTrees back = ReadGeoTrees(Path(name), {});
    ASSERT_EQ(back.rows.size(), rows.size()) << name;
    for (size_t i = 0; i < rows.size(); ++i) {
      EXPECT_EQ(back.rows[i].attributes, rows[i].attributes) << name << " tree " << i + 1;
      EXPECT_EQ(back.rows[i].null_attributes, rows[i].null_attributes) << name;
    }
    EXPECT_NE(back.crs_wkt.find("2959"), std::string::npos) << name;
  }
}

TEST_F(GeoIoTest, GeoPackageLayersAreAddedAndChosen) {
  std::vector<MapTreeRow> rows = TrickyRows();
  const std::string path = Path("p.gpkg");
  WriteGeoTrees(path, TreeFormat::kGeoPackage, rows, "", "a");
  rows.pop_back();
  WriteGeoTrees(path, TreeFormat::kGeoPackage, rows, "", "b");
  rows.pop_back();
  WriteGeoTrees(path, TreeFormat::kGeoPackage, rows, "", "a");  // replaces a
  const auto read_layer = [&](const std::string& layer) {
    TreeFileOptions options;
    options.layer = layer;
    return ReadGeoTrees(path, options);
  };
  EXPECT_EQ(read_layer("a").rows.size(), 1u);
  const GeoTrees b = read_layer("b");
  EXPECT_EQ(b.rows.size(), 2u);
  EXPECT_EQ(b.crs_wkt, "");  // the undefined Cartesian SRS is no CRS
  try {                      // a, replaced, comes after b now
    ReadGeoTrees(path, {});
    ADD_FAILURE() << "two point layers read without --layer";
  } catch (const CsvError& e) {
    EXPECT_EQ(std::string(e.what()), path +
                                         ": several layers have points (layers: b (Point), a "
                                         "(Point)): name the trees' layer with --layer NAME");
  }
}

}  // namespace
}  // namespace forestmap::client
