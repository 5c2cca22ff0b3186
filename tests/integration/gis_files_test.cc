// GIS files as a new user meets them, through the built `forestmap` binary against a
// real in-process server: exports into an existing GeoPackage, atomic replacement, attributes
// GIS formats cannot hold as named, maps without a CRS, several layers, typed fields, text that
// is not UTF-8, shapefiles' encoding, field names and missing .dbf. Files are checked with GDAL's
// own ogrinfo / ogr2ogr (gdal-bin).

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/cli_run.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;

using Result = testing_util::CliResult;
using testing_util::ReadWholeFile;

// The names in `dir` (temporary files left behind show up here).
std::vector<std::string> Listing(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name != "stdout" && name != "stderr") names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

bool Has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

class GisFilesTest : public ::testing::Test {
 protected:
  GisFilesTest()
      : store_(":memory:"),
        service_(store_, {}),
        runner_("127.0.0.1:0", service_),
        client_(runner_.address()) {}

  void SetUp() override { dir_ = testing_util::FreshTestFolder("forestmap_gis_test"); }
  void TearDown() override { fs::remove_all(dir_); }

  Result Shell(const std::string& command) { return testing_util::RunCapturing(command, dir_); }
  Result Cli(const std::string& args) {
    return Shell("'" FORESTMAP_CLI_PATH "' --server " + runner_.address() + " " + args);
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void Write(const std::string& name, const std::string& text) const {
    std::ofstream(dir_ / name, std::ios::binary) << text;
  }
  // A map of three trees on a local 0-150 m grid (no CRS) with `header` attributes.
  void CreateLocal(const std::string& name, const std::string& header,
                   const std::vector<std::string>& values, const std::string& extra = "") {
    std::string csv = "x,y,dbh," + header + "\n";
    const char* positions[] = {"10,120,0.3,", "75.5,140,0.25,", "150,95,0.4,"};
    for (size_t i = 0; i < values.size(); ++i) csv += positions[i] + values[i] + "\n";
    Write(name + ".csv", csv);
    const Result created =
        Cli("map create " + name + " --trees '" + Path(name + ".csv") + "' " + extra);
    ASSERT_EQ(created.exit_code, 0) << created.err;
  }
  // `map create COPY --trees FILE`, then the attributes of COPY's trees.
  std::vector<std::map<std::string, std::string>> ReadBack(const std::string& copy,
                                                           const std::string& file,
                                                           const std::string& extra = "") {
    const Result created = Cli("map create " + copy + " --trees '" + file + "' " + extra);
    EXPECT_EQ(created.exit_code, 0) << created.err;
    std::vector<std::map<std::string, std::string>> attributes;
    if (created.exit_code != 0) return attributes;
    for (const auto& tree : client_.ExportTrees(copy).trees) attributes.push_back(tree.attributes);
    return attributes;
  }

  storage::SqliteMapStore store_;
  server::ForestMapService service_;
  server::ServerRunner runner_;
  client::ForestMapClient client_;
  fs::path dir_;
};

TEST_F(GisFilesTest, GeoPackageExportAddsOneLayerAndLeavesTheOthers) {
  CreateLocal("plot_a", "sp", {"oak", "ash", "elm"}, "--crs EPSG:2959");
  CreateLocal("plot_b", "sp", {"fir", "yew", "box"}, "--crs EPSG:2959");
  const std::string project = Path("project.gpkg");
  ASSERT_EQ(Cli("map export plot_a --out '" + project + "'").exit_code, 0);
  const Result second = Cli("map export plot_b --out '" + project + "'");
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_TRUE(Has(second.err, "(layer 'plot_b')")) << second.err;
  ASSERT_EQ(Cli("map export plot_a --out '" + project + "'").exit_code, 0);  // replaces plot_a
  const Result info = Shell("ogrinfo -so '" + project + "'");
  EXPECT_TRUE(Has(info.out, ": plot_b (Point)")) << info.out;
  EXPECT_TRUE(Has(info.out, ": plot_a (Point)")) << info.out;
  EXPECT_FALSE(Has(info.out, "3: ")) << info.out;
  EXPECT_TRUE(Has(Shell("ogrinfo -so '" + project + "' plot_a").out, "Feature Count: 3"));

  // Reading it back: two point layers need --layer; a boundary polygon is no tree layer.
  const Result ambiguous = Cli("map create c --trees '" + project + "'");
  EXPECT_EQ(ambiguous.exit_code, 1);
  EXPECT_TRUE(Has(ambiguous.err, "project.gpkg: several layers have points (layers: "))
      << ambiguous.err;
  EXPECT_TRUE(Has(ambiguous.err, "plot_a (Point)") && Has(ambiguous.err, "--layer NAME"))
      << ambiguous.err;
  const auto b = ReadBack("c", project, "--layer plot_b");
  ASSERT_EQ(b.size(), 3u);
  EXPECT_EQ(b[0].at("sp"), "fir");
  Write("boundary.geojson", R"({"type": "FeatureCollection", "features": [{"type": "Feature",
    "properties": {"name": "stand"}, "geometry": {"type": "Polygon",
    "coordinates": [[[0, 0], [200, 0], [200, 200], [0, 0]]]}}]})");
  const std::string site = Path("site.gpkg");
  ASSERT_EQ(Shell("ogr2ogr -f GPKG '" + site + "' '" + Path("boundary.geojson") +
                  "' -nln boundary -a_srs EPSG:2959")
                .exit_code,
            0);
  ASSERT_EQ(Cli("map export plot_a --out '" + site + "'").exit_code, 0);
  EXPECT_EQ(ReadBack("d", site).size(), 3u);
  const Result missing = Cli("map create e --trees '" + site + "' --layer nosuch");
  EXPECT_TRUE(Has(missing.err,
                  "--layer nosuch: no such layer (layers: boundary (Polygon), "
                  "plot_a (Point))"))
      << missing.err;
}

TEST_F(GisFilesTest, ExportsReplaceFilesWholeOrNotAtAll) {
  CreateLocal("plot", "sp", {"oak", "ash", "elm"}, "--crs EPSG:2959");
  Write("empty.geojson", "");  // what a failed export used to leave
  const Result over = Cli("map export plot --out '" + Path("empty.geojson") + "'");
  ASSERT_EQ(over.exit_code, 0) << over.err;
  EXPECT_EQ(ReadBack("copy", Path("empty.geojson")).size(), 3u);
  // A failed export (a file that is no GeoPackage) leaves the file as it was, and no temporary.
  Write("notes.gpkg", "my notes");
  const Result failed = Cli("map export plot --out '" + Path("notes.gpkg") + "'");
  EXPECT_EQ(failed.exit_code, 1);
  EXPECT_TRUE(Has(failed.err, "notes.gpkg: exists and is not a GeoPackage")) << failed.err;
  EXPECT_EQ(ReadWholeFile(dir_ / "notes.gpkg"), "my notes");
  // A shapefile replaces every part of an older one (its .prj of another CRS too).
  CreateLocal("local", "sp", {"oak", "ash", "elm"});
  ASSERT_EQ(Cli("map export plot --out '" + Path("t.shp") + "'").exit_code, 0);
  ASSERT_TRUE(fs::exists(dir_ / "t.prj"));
  ASSERT_EQ(Cli("map export local --out '" + Path("t.shp") + "'").exit_code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "t.prj"));
  // An extension that names another format is refused, creating nothing.
  const Result contradiction = Cli("map export plot --format shp --out '" + Path("t.csv") + "'");
  EXPECT_EQ(contradiction.exit_code, 1);
  EXPECT_TRUE(Has(contradiction.err, "--format shp and --out " + Path("t.csv") +
                                         " disagree: name the file " + Path("t.shp")))
      << contradiction.err;
  EXPECT_FALSE(fs::exists(dir_ / "t.csv"));
  const Result no_directory = Cli("map export plot --out '" + Path("none/t.shp") + "'");
  EXPECT_TRUE(Has(no_directory.err, "t.shp: cannot write: no directory " + Path("none")))
      << no_directory.err;
  EXPECT_EQ(Listing(dir_),
            (std::vector<std::string>{"empty.geojson", "local.csv", "notes.gpkg", "plot.csv",
                                      "t.cpg", "t.dbf", "t.shp", "t.shx"}));
}

TEST_F(GisFilesTest, AttributesEveryFormatCannotNameAreRenamedAndEveryMapExports) {
  // Species and species (one GeoPackage column), QGIS's fid, and geom.
  CreateLocal("plot", "Species,species,fid,geom", {"Oak,o,1,a", "Ash,a,2,b", "Elm,e,3,c"});
  const std::map<std::string, std::string> gis = {
      {"Species", "Oak"}, {"attr_species", "o"}, {"attr_fid", "1"}, {"attr_geom", "a"}};
  std::map<std::string, std::string> shapefile = gis;  // names of 10 characters
  shapefile.erase("attr_species");
  shapefile["attr_speci"] = "o";
  const std::map<std::string, std::string> csv = {
      {"Species", "Oak"}, {"attr_species", "o"}, {"fid", "1"}, {"geom", "a"}};
  for (const std::string name : {"r.gpkg", "r.geojson", "r.shp", "rc.csv"}) {
    const auto& expected = name == "rc.csv" ? csv : name == "r.shp" ? shapefile : gis;
    const Result exported = Cli("map export plot --out '" + Path(name) + "'");
    ASSERT_EQ(exported.exit_code, 0) << name << ": " << exported.err;
    const std::string copy = "copy_" + fs::path(name).extension().string().substr(1);
    const auto back = ReadBack(copy, Path(name));
    ASSERT_EQ(back.size(), 3u) << name;
    EXPECT_EQ(back[0], expected) << name;
  }
}

TEST_F(GisFilesTest, MapsWithoutCrsReadBackWithoutOne) {
  CreateLocal("local", "h", {"1", "2", "3"});
  for (const std::string name : {"b.geojson", "b.gpkg", "b.shp", "c.csv"}) {
    ASSERT_EQ(Cli("map export local --out '" + Path(name) + "'").exit_code, 0) << name;
    const std::string copy = "copy_" + fs::path(name).extension().string().substr(1);
    EXPECT_EQ(ReadBack(copy, Path(name)).size(), 3u) << name;
    EXPECT_EQ(client_.GetMap(copy).crs(), "") << name;
  }
  EXPECT_TRUE(
      Has(Shell("ogrinfo -so -al '" + Path("b.gpkg") + "'").out, "Undefined Cartesian SRS"));
  EXPECT_TRUE(Has(ReadWholeFile(dir_ / "b.geojson"), "\"crs\": null,"))
      << ReadWholeFile(dir_ / "b.geojson");
  // A local grid small enough to look like degrees reads back without a CRS all the same.
  Write("small.csv", "x,y\n10,20\n12,21\n15,25\n");
  ASSERT_EQ(Cli("map create small --trees '" + Path("small.csv") + "'").exit_code, 0);
  ASSERT_EQ(Cli("map export small --out '" + Path("small.geojson") + "'").exit_code, 0);
  EXPECT_EQ(ReadBack("small_back", Path("small.geojson")).size(), 3u);
  EXPECT_EQ(client_.GetMap("small_back").crs(), "");
  // GeoJSON without a crs member in longitude and latitude is still WGS 84 (RFC 7946).
  Write("lonlat.geojson", R"({"type": "FeatureCollection", "features": [{"type": "Feature",
    "properties": {}, "geometry": {"type": "Point", "coordinates": [-75.6, 46.1]}}]})");
  const Result degrees = Cli("map create deg --trees '" + Path("lonlat.geojson") + "'");
  EXPECT_TRUE(Has(degrees.err, "its CRS EPSG:4326")) << degrees.err;

  // A stale h.prj goes when a map without a CRS is exported to h.csv.
  Write("h.prj", "EPSG:2959\n");
  ASSERT_EQ(Cli("map export local --out '" + Path("h.csv") + "'").exit_code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "h.prj"));
  // An upper-case .PRJ is read; a garbage one is an error naming it.
  Write("h.PRJ", "EPSG:2959\n");
  ASSERT_EQ(ReadBack("upper", Path("h.csv")).size(), 3u);
  EXPECT_EQ(client_.GetMap("upper").crs_epsg(), 2959);
  Write("h.PRJ", "garbage, not a CRS\n");
  const Result garbage = Cli("map create garbage --trees '" + Path("h.csv") + "'");
  EXPECT_EQ(garbage.exit_code, 1);
  EXPECT_TRUE(Has(garbage.err, Path("h.PRJ") + ": not a CRS PROJ knows")) << garbage.err;
}

// One export never replaces another's files, and names only what it writes: x.csv's CRS file
// x.prj is also the shapefile x.shp's; x.kml is no format we write (it used to be CSV, silently);
// t.SHP is written by GDAL as t.shp, and said so.
TEST_F(GisFilesTest, ExportsNeverClobberAnotherExportsFilesNorWriteUnknownFormats) {
  CreateLocal("plot", "sp", {"oak", "ash", "elm"}, "--crs EPSG:2959");
  ASSERT_EQ(Cli("map export plot --out '" + Path("x.shp") + "'").exit_code, 0);
  const std::string prj = ReadWholeFile(dir_ / "x.prj");
  const Result csv = Cli("map export plot --out '" + Path("x.csv") + "'");
  EXPECT_EQ(csv.exit_code, 1);
  EXPECT_TRUE(Has(csv.err, "would replace that of " + Path("x.shp"))) << csv.err;
  EXPECT_FALSE(fs::exists(dir_ / "x.csv"));
  EXPECT_EQ(ReadWholeFile(dir_ / "x.prj"), prj);
  EXPECT_TRUE(Has(Shell("ogrinfo -so -al '" + Path("x.shp") + "'").out, "EPSG\",2959"));
  ASSERT_EQ(Cli("map export plot --out '" + Path("y.csv") + "'").exit_code, 0);
  const Result shp = Cli("map export plot --out '" + Path("y.shp") + "'");
  EXPECT_EQ(shp.exit_code, 1);
  EXPECT_TRUE(Has(shp.err, "would replace that of " + Path("y.csv"))) << shp.err;

  const std::vector<std::string> before = Listing(dir_);
  for (const std::string name : {"t.kml", "t.fgb", "t.txt"}) {
    const Result unknown = Cli("map export plot --out '" + Path(name) + "'");
    EXPECT_EQ(unknown.exit_code, 1) << name;
    EXPECT_TRUE(Has(unknown.err, "name it .csv, .geojson, .gpkg or .shp")) << unknown.err;
  }
  EXPECT_EQ(Listing(dir_), before);
  const Result upper = Cli("map export plot --out '" + Path("t.SHP") + "'");
  ASSERT_EQ(upper.exit_code, 0) << upper.err;
  EXPECT_TRUE(Has(upper.err, "to " + Path("t.shp"))) << upper.err;
  EXPECT_TRUE(fs::exists(dir_ / "t.shp"));
}

// --to-crs EPSG:4326 writes the GeoJSON web tools expect (RFC 7946: longitude, latitude, no "crs"
// member), each point where cs2cs puts it; CSV and the other formats take any CRS too.
TEST_F(GisFilesTest, ExportsReprojectIntoAnotherCrsAndGeoJsonInWgs84IsRfc7946) {
  Write("utm.csv", "x,y,dbh\n300000,5100000,0.3\n300050.5,5100020.25,0.4\n");
  ASSERT_EQ(Cli("map create utm --crs EPSG:32618 --trees '" + Path("utm.csv") + "'").exit_code, 0);
  const Result web = Cli("map export utm --to-crs EPSG:4326 --out '" + Path("w.geojson") + "'");
  ASSERT_EQ(web.exit_code, 0) << web.err;
  const std::string text = ReadWholeFile(dir_ / "w.geojson");
  EXPECT_FALSE(Has(text, "\"crs\"")) << text;
  const Result expected = Shell(
      "printf '300000 5100000\\n300050.5 5100020.25\\n' | "
      "cs2cs -f %.8f EPSG:32618 OGC:CRS84");
  ASSERT_EQ(expected.exit_code, 0) << expected.err;
  std::istringstream lines(expected.out);
  const Result csv = Cli("map export utm --to-crs EPSG:4326 --out '" + Path("w.csv") + "'");
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  std::istringstream rows(ReadWholeFile(dir_ / "w.csv"));
  std::string row;
  std::getline(rows, row);  // header
  for (int i = 0; i < 2; ++i) {
    double lon = 0, lat = 0, x = 0, y = 0;
    char comma = 0;
    int64_t id = 0;
    lines >> lon >> lat;
    std::getline(lines, row);  // the rest of cs2cs' line
    ASSERT_TRUE(std::getline(rows, row));
    std::istringstream(row) >> id >> comma >> x >> comma >> y;
    EXPECT_NEAR(x, lon, 1e-8) << row;
    EXPECT_NEAR(y, lat, 1e-8) << row;
    EXPECT_TRUE(Has(text, "[ " + std::to_string(lon).substr(0, 9))) << text;
  }
  EXPECT_TRUE(Has(ReadWholeFile(dir_ / "w.prj"), "WGS 84"));
  const Result bad = Cli("map export utm --to-crs EPSG:99999999 --out '" + Path("b.gpkg") + "'");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_TRUE(Has(bad.err, "--to-crs EPSG:99999999")) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ / "b.gpkg"));
}

// `detect` on a scan without a CRS writes no .prj beside its CSV and removes an old one.
TEST_F(GisFilesTest, DetectWithoutCrsLeavesNoOldPrj) {
  std::string scan;
  for (int i = 0; i < 400; ++i) {
    scan += std::to_string(i % 20 * 0.5) + " " + std::to_string(i / 20 * 0.5) + " 0.01\n";
  }
  Write("scan.xyz", scan);
  Write("trees.prj", "EPSG:2959\n");
  const Result detected =
      Cli("detect '" + Path("scan.xyz") + "' --out '" + Path("trees.csv") + "'");
  ASSERT_EQ(detected.exit_code, 0) << detected.err;
  EXPECT_TRUE(fs::exists(dir_ / "trees.csv"));
  EXPECT_FALSE(fs::exists(dir_ / "trees.prj"));
}

TEST_F(GisFilesTest, NumbersAreExportedAsNumbersAndReadBackAsWritten) {
  CreateLocal("plot", "Ht,count,code,mixed", {"62,3,007,1", "6,12,010,2.5", "16.8,-4,x1,NA"});
  for (const std::string name : {"n.gpkg", "n.shp", "n.geojson"}) {
    ASSERT_EQ(Cli("map export plot --out '" + Path(name) + "'").exit_code, 0);
    const Result info = Shell("ogrinfo -so -al '" + Path(name) + "'");
    EXPECT_TRUE(Has(info.out, "\nHt: Real")) << name << info.out;
    EXPECT_TRUE(Has(info.out, "\ncount: Integer")) << name << info.out;
    EXPECT_TRUE(Has(info.out, "\ncode: String")) << name << info.out;  // 007 is no integer
    EXPECT_TRUE(Has(info.out, "\nmixed: Real")) << name << info.out;
    // QGIS's Ht > 5 compares numbers: all three trees, not the 6 alone as text.
    const Result tall = Shell("ogrinfo -al -q -where 'Ht > 10' '" + Path(name) + "'");
    EXPECT_TRUE(Has(tall.out, "Ht (Real) = 62") && Has(tall.out, "Ht (Real) = 16.8") &&
                !Has(tall.out, "Ht (Real) = 6\n"))
        << name << tall.out;
    const std::string copy = "copy_" + fs::path(name).extension().string().substr(1);
    const auto original = client_.ExportTrees("plot").trees;
    const auto read = ReadBack(copy, Path(name));
    ASSERT_EQ(read.size(), original.size()) << name;
    for (size_t i = 0; i < read.size(); ++i) EXPECT_EQ(read[i], original[i].attributes) << name;
  }
}

// A column has one type in every format: 1e-20 (a trigonometry remainder beside ordinary
// numbers) keeps its column Real in the shapefile too, which rounds it to its 15 decimals and
// says so (it was String there and Real in the GeoPackage).
TEST_F(GisFilesTest, AColumnHasOneTypeInEveryFormat) {
  CreateLocal("plot", "tiny", {"0.5", "1e-20", "2"});
  for (const std::string name : {"t.gpkg", "t.shp", "t.geojson"}) {
    const Result exported = Cli("map export plot --out '" + Path(name) + "'");
    ASSERT_EQ(exported.exit_code, 0) << exported.err;
    EXPECT_TRUE(Has(Shell("ogrinfo -so -al '" + Path(name) + "'").out, "\ntiny: Real")) << name;
    EXPECT_EQ(Has(exported.err, "1e-20 (and any like it) is rounded"), name == "t.shp")
        << exported.err;
  }
}

TEST_F(GisFilesTest, TextThatIsNotUtf8IsRefusedNamingFileFeatureAndField) {
  Write("latin.geojson",
        "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\","
        "\"properties\":{\"sp\":\"H\xEAtre\"},\"geometry\":{\"type\":\"Point\","
        "\"coordinates\":[1,2]}}]}");
  const Result geojson = Cli("map create a --trees '" + Path("latin.geojson") + "'");
  EXPECT_EQ(geojson.exit_code, 1);
  EXPECT_TRUE(Has(geojson.err, "latin.geojson: feature 1: field 'sp': not UTF-8 text (byte 0xEA"))
      << geojson.err;
  EXPECT_FALSE(Has(geojson.err, "libprotobuf")) << geojson.err;
  // A Latin-1 shapefile without its .cpg.
  Write("utf8.geojson",
        "{\"type\":\"FeatureCollection\",\"features\":[{\"type\":\"Feature\","
        "\"properties\":{\"sp\":\"H\xC3\xAAtre\"},\"geometry\":{\"type\":"
        "\"Point\",\"coordinates\":[1,2]}}]}");
  ASSERT_EQ(Shell("ogr2ogr -f 'ESRI Shapefile' -lco ENCODING=ISO-8859-1 '" + Path("l.shp") + "' '" +
                  Path("utf8.geojson") + "'")
                .exit_code,
            0);
  fs::remove(dir_ / "l.cpg");
  const Result shapefile = Cli("map create b --trees '" + Path("l.shp") + "'");
  EXPECT_EQ(shapefile.exit_code, 1);
  EXPECT_TRUE(Has(shapefile.err, "l.shp: feature 1: field 'sp': not UTF-8 text")) << shapefile.err;
  EXPECT_TRUE(Has(shapefile.err, ".cpg")) << shapefile.err;
  EXPECT_TRUE(client_.ListMaps().empty());
}

TEST_F(GisFilesTest, ShapefilesAreUtf8WithACpgAndSayWhichFieldsTheyRenamed) {
  CreateLocal("plot", "sp,total_height_cm,total_height_m",
              {"Ch\xC3\xAAne \xE6\xA9\xA1,1500,15", "Ash,2000,20", "Elm,1800,18"});
  const Result exported = Cli("map export plot --out '" + Path("s.shp") + "'");
  ASSERT_EQ(exported.exit_code, 0) << exported.err;
  EXPECT_TRUE(Has(ReadWholeFile(dir_ / "s.cpg"), "UTF-8")) << ReadWholeFile(dir_ / "s.cpg");
  EXPECT_TRUE(Has(exported.err, "warning: " + Path("s.shp") +
                                    ": field 'total_height_cm' is written as 'total_heig'"))
      << exported.err;
  EXPECT_TRUE(Has(exported.err, "field 'total_height_m' is written as 'total_he_1'"))
      << exported.err;
  const auto back = ReadBack("copy", Path("s.shp"));
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back[0].at("sp"), "Ch\xC3\xAAne \xE6\xA9\xA1");
  EXPECT_EQ(back[0].at("total_heig"), "1500");
  // Without its .dbf a shapefile has positions only: refused, naming the .dbf.
  fs::remove(dir_ / "s.dbf");
  const Result no_dbf = Cli("map create nodbf --trees '" + Path("s.shp") + "'");
  EXPECT_EQ(no_dbf.exit_code, 1);
  EXPECT_TRUE(Has(no_dbf.err, Path("s.shp") + ": no s.dbf beside it")) << no_dbf.err;
}

// Where each of `names` first appears in `text` after `prefix` (npos when it does not).
std::vector<size_t> Positions(const std::string& text, const std::vector<std::string>& names,
                              const std::string& prefix, const std::string& suffix) {
  std::vector<size_t> positions;
  for (const std::string& name : names) positions.push_back(text.find(prefix + name + suffix));
  return positions;
}

// Every name found, in the order given.
void ExpectInOrder(const std::vector<size_t>& positions, const std::string& text) {
  for (size_t i = 0; i < positions.size(); ++i) {
    EXPECT_NE(positions[i], std::string::npos) << i << "\n" << text;
    if (i > 0) {
      EXPECT_LT(positions[i - 1], positions[i]) << i << "\n" << text;
    }
  }
}

TEST_F(GisFilesTest, ExportsKeepTheCrewsColumnOrderInEveryFormat) {
  const std::vector<std::string> crew = {"species", "height", "crown", "plot_id"};
  CreateLocal("crew", "species,height,crown,plot_id",
              {"oak,21.5,6,P7", "ash,18,4.5,P7", "elm,25,7,P8"}, "--crs EPSG:2959");
  // An append keeps the map's order and adds the file's new columns after it, in its order.
  Write("more.csv", "x,y,zone,plot_id,alpha,species\n20,100,z1,P9,a,fir\n");
  const Result appended = Cli("map upload crew --trees '" + Path("more.csv") + "'");
  ASSERT_EQ(appended.exit_code, 0) << appended.err;
  std::vector<std::string> all = crew;
  all.insert(all.end(), {"zone", "alpha"});

  const Result csv = Cli("map export crew");
  ASSERT_EQ(csv.exit_code, 0) << csv.err;
  EXPECT_EQ(csv.out.substr(0, csv.out.find('\n')),
            "id,x,y,z,dbh,species,height,crown,plot_id,zone,alpha");
  for (const std::string file : {"out.gpkg", "out.shp", "out.geojson"}) {
    const Result exported = Cli("map export crew --out '" + Path(file) + "'");
    ASSERT_EQ(exported.exit_code, 0) << exported.err;
    const Result info = Shell("ogrinfo -so -al '" + Path(file) + "'");
    ASSERT_EQ(info.exit_code, 0) << info.err;
    ExpectInOrder(Positions(info.out, all, "\n", ": "), info.out);
  }
  // GeoJSON's properties are in that order too, in every feature.
  const std::string geojson = ReadWholeFile(dir_ / "out.geojson");
  ExpectInOrder(Positions(geojson, crew, "\"", "\": "), geojson);

  // A GeoPackage read back gives the same order: its fields' order is the file's.
  ASSERT_EQ(Cli("map create again --trees '" + Path("out.gpkg") + "'").exit_code, 0);
  const Result again = Cli("map export again");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.out.substr(0, again.out.find('\n')),
            "id,x,y,z,dbh,species,height,crown,plot_id,zone,alpha");
  // Replacing the trees replaces the order.
  Write("new.csv", "x,y,b_col,a_col\n1,2,b,a\n");
  ASSERT_EQ(Cli("map upload crew --replace --trees '" + Path("new.csv") + "'").exit_code, 0);
  const Result replaced = Cli("map export crew");
  EXPECT_EQ(replaced.out.substr(0, replaced.out.find('\n')), "id,x,y,z,dbh,b_col,a_col");
}

}  // namespace
}  // namespace forestmap
