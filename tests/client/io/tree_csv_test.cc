#include "client/io/tree_csv.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include "client/io/utf8.h"
#include "tests/client/io/csv_test_util.h"
#include "tests/shared_data.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;

using testing_util::CsvErrorOf;

std::string MapError(const std::string& content) {
  return CsvErrorOf([&] { ParseMapTreesCsv(content, "t.csv"); });
}

std::string DetectionError(const std::string& content) {
  return CsvErrorOf([&] { ParseDetectedTreesCsv(content, "d.csv"); });
}

TEST(TreeCsvTest, FindsColumnsByNameAndAlias) {
  for (const char* header : {"x,y,z,dbh,id", "x_m,y_m,z_m,dbh_m,tree_id", " X , Y ,Z,DBH,ID",
                             "Tree_ID,X_M,Y_M,Z_M,Dbh_M", "\"x\",\"y\",\"z\",\"dbh\",\"id\""}) {
    SCOPED_TRACE(header);
    // The same values in the header's column order.
    const bool id_first = std::string(header).rfind("Tree_ID", 0) == 0;
    const std::string row = id_first ? "7,1.5,-2.25,3,0.31" : "1.5,-2.25,3,0.31,7";
    const auto rows = ParseMapTreesCsv(std::string(header) + "\n" + row + "\n", "t.csv");
    ASSERT_EQ(rows.size(), 1u);
    EXPECT_EQ(rows[0].id, 7);
    EXPECT_EQ(rows[0].x, 1.5);
    EXPECT_EQ(rows[0].y, -2.25);
    EXPECT_EQ(rows[0].z, 3.0);
    EXPECT_EQ(rows[0].dbh, 0.31);
    EXPECT_TRUE(rows[0].attributes.empty());
  }
}

TEST(TreeCsvTest, KeepsOtherColumnsAsAttributes) {
  const auto rows = ParseMapTreesCsv(
      "tree_id,x_m,y_m,dbh_m,height_m,species\n1,14.4,17.4,0.635,23.6,beech\n", "t.csv");
  ASSERT_EQ(rows.size(), 1u);
  const std::map<std::string, std::string> expected = {{"height_m", "23.6"}, {"species", "beech"}};
  EXPECT_EQ(rows[0].attributes, expected);
  EXPECT_FALSE(rows[0].z.has_value());
}

TEST(TreeCsvTest, ReadsQuotedFieldsAsRWritesThem) {
  const std::string content =
      "\xEF\xBB\xBF\"\",\"x\",\"y\",\"note\"\r\n"
      "\"1\",\"1.5\",\"2\",\"Pinus \"\"big\"\", sylvestris\"\r\n"
      "\"2\", 3 , 4 ,\"two\nlines\"\r\n"
      "\r\n";
  const auto rows = ParseMapTreesCsv(content, "r.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].x, 1.5);
  EXPECT_EQ(rows[0].attributes.at("note"), "Pinus \"big\", sylvestris");
  EXPECT_EQ(rows[1].x, 3.0);
  EXPECT_EQ(rows[1].attributes.at("note"), "two\nlines");
  // The unnamed first column holds R's row names: ignored.
  EXPECT_EQ(rows[0].attributes.size(), 1u);
}

TEST(TreeCsvTest, EmptyAndNaMeanUnknown) {
  const auto rows = ParseMapTreesCsv(
      "id,x,y,z,dbh,species\n"
      "1,0,0,,NA,\n"
      "2,0,1,NaN,nan,NA\n"
      "3,0,2,1,0.2,\"NA\"\n"
      ",0,3,1,0.2,\"\"\n",
      "t.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_FALSE(rows[0].z.has_value());
  EXPECT_FALSE(rows[0].dbh.has_value());
  EXPECT_TRUE(rows[0].attributes.empty());
  EXPECT_EQ(rows[0].null_attributes, std::set<std::string>{"species"});  // empty: unknown
  EXPECT_FALSE(rows[1].z.has_value());
  EXPECT_FALSE(rows[1].dbh.has_value());
  EXPECT_TRUE(rows[1].attributes.empty());  // unquoted NA: an unknown string, a null attribute
  EXPECT_EQ(rows[1].null_attributes, std::set<std::string>{"species"});
  EXPECT_EQ(rows[2].attributes.at("species"), "NA");  // quoted: the literal string
  EXPECT_TRUE(rows[2].null_attributes.empty());
  EXPECT_FALSE(rows[3].id.has_value());
  EXPECT_EQ(rows[3].attributes.at("species"), "");
}

TEST(TreeCsvTest, HeaderOnlyGivesNoRows) {
  EXPECT_TRUE(ParseMapTreesCsv("x,y\n", "t.csv").empty());
  EXPECT_TRUE(ParseDetectedTreesCsv("x,y\n\n", "d.csv").empty());
  EXPECT_TRUE(ParseFramesCsv("frame,x,y\n", "f.csv").empty());
}

TEST(TreeCsvTest, MalformedInputNamesFileLineAndColumn) {
  EXPECT_EQ(MapError(""), "t.csv: empty file (no header)");
  EXPECT_EQ(MapError(" \r\n\n"), "t.csv: empty file (no header)");
  EXPECT_EQ(MapError("a,x,c\n1,2,3\n"), "t.csv:1: missing required column 'y' (columns: a,x,c)");
  EXPECT_EQ(MapError("x,y\n1,2\n\nabc,3\n"), "t.csv:4: column 'x': 'abc' is not a number");
  EXPECT_EQ(MapError("x,y\n1,2abc\n"), "t.csv:2: column 'y': '2abc' is not a number");
  EXPECT_EQ(MapError("x,y,z\n1,2,3\n1,2\n"), "t.csv:3: 2 fields, header has 3");
  EXPECT_EQ(MapError("x,y\n1,2,3\n"), "t.csv:2: 3 fields, header has 2");
  EXPECT_EQ(MapError("x_m,y\nNaN,2\n"), "t.csv:2: column 'x_m': 'NaN' is not allowed (required)");
  EXPECT_EQ(MapError("x,y\n1,\n"), "t.csv:2: column 'y': missing value (required)");
  EXPECT_EQ(MapError("x,y\n1,NA\n"), "t.csv:2: column 'y': 'NA' is not allowed (required)");
  EXPECT_EQ(MapError("x,y\ninf,2\n"), "t.csv:2: column 'x': 'inf' is not a finite number");
  EXPECT_EQ(MapError("x,y,dbh\n1,2,-Infinity\n"),
            "t.csv:2: column 'dbh': '-Infinity' is not a finite number");
  EXPECT_EQ(MapError("x,y,z\n1,2,1e999\n"), "t.csv:2: column 'z': '1e999' is out of range");
  EXPECT_EQ(MapError("x,y,dbh\n1,2,-0.3\n"), "t.csv:2: column 'dbh': '-0.3' is negative");
  EXPECT_EQ(MapError("tree_id,x,y\n12,0,0\n3,0,0\n\n12,1,1\n"),
            "t.csv:5: column 'tree_id': duplicate tree id 12 (lines 2 and 5)");
  EXPECT_EQ(MapError("x,x_m,y\n1,1,2\n"), "t.csv:1: columns 'x' and 'x_m' both give 'x'");
  EXPECT_EQ(MapError("x,y,s,s\n1,2,a,b\n"), "t.csv:1: duplicate column 's'");
  EXPECT_EQ(MapError("x,y,s\n1,2,\"abc\n"), "t.csv:2: column 's': unterminated quoted field");
  EXPECT_EQ(MapError("x,y,s\n1,2,\"a\"b\n"),
            "t.csv:2: column 's': unexpected text after a closing quote");
}

// Issue 15: a Latin-1 byte in an attribute made the server unable to decode that upload
// message; the client now names the file, line and column before sending anything.
TEST(TreeCsvTest, AttributesMustBeUtf8) {
  std::string content = "x,y,species\n";
  for (int i = 0; i < 12; ++i) content += std::to_string(i) + ",0,pine\n";
  EXPECT_EQ(ParseMapTreesCsv(content + "1,2,\xc3\xa9pic\xc3\xa9"
                                       "a\n",
                             "t.csv")
                .back()
                .attributes.at("species"),
            "\xc3\xa9pic\xc3\xa9"
            "a");  // UTF-8 is kept as it is
  content +=
      "7,0,\xe9pic\xe9"
      "a\n";  // Latin-1 "épicéa" on line 14
  EXPECT_EQ(MapError(content),
            "t.csv:14: column 'species': the value is not valid UTF-8 (byte 0xe9 at offset 0); "
            "save the file as UTF-8");
  EXPECT_EQ(MapError("x,y,note\n1,2,ok \xed\xa0\x80\n").rfind("t.csv:2: column 'note'", 0), 0u);
  EXPECT_NE(MapError("x,y,s\xff\n1,2,a\n").find("the column name is not valid UTF-8"),
            std::string::npos);
  EXPECT_EQ(FirstInvalidUtf8("a\xc0\xaf"), 1u);         // overlong '/'
  EXPECT_EQ(FirstInvalidUtf8("\xf4\x90\x80\x80"), 0u);  // beyond U+10FFFF
  EXPECT_EQ(FirstInvalidUtf8("ab\xe2\x82"), 2u);        // truncated
  EXPECT_EQ(FirstInvalidUtf8("\xf0\x9f\x8c\xb2 tree"), std::nullopt);
}

TEST(TreeCsvTest, FileErrorsNameTheFile) {
  const std::string missing = (fs::temp_directory_path() / "forestmap_no_such_file.csv").string();
  EXPECT_EQ(CsvErrorOf([&] { ReadMapTreesCsv(missing); }),
            missing + ": cannot open: No such file or directory");
  const std::string dir = fs::temp_directory_path().string();
  EXPECT_EQ(CsvErrorOf([&] { ReadFramesCsv(dir); }), dir + ": is a directory");
}

TEST(TreeCsvTest, DetectionsReadAxisScoreAndFrame) {
  const auto rows = ParseDetectedTreesCsv(
      "frame,x,y,z,dbh,axis_x,axis_y,axis_z,score,clusters\n"
      "4,1,2,3,0.25,0,0,1,0.5,7\n"
      "4,5,6,,,,,,nan,1\n",
      "d.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].frame, 4);
  EXPECT_EQ(rows[0].tree.position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(rows[0].tree.dbh, 0.25);
  EXPECT_EQ(rows[0].tree.axis, Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(rows[0].tree.score, 0.5);
  // Unknown z is 0 (sensor height); unknown dbh and score NaN; unknown axis zero.
  EXPECT_EQ(rows[1].tree.position, Eigen::Vector3d(5, 6, 0));
  EXPECT_TRUE(std::isnan(rows[1].tree.dbh));
  EXPECT_TRUE(std::isnan(rows[1].tree.score));
  EXPECT_FALSE(rows[1].tree.HasAxis());

  const auto plain = ParseDetectedTreesCsv("X_M,Y_M\n1,2\n", "d.csv");
  ASSERT_EQ(plain.size(), 1u);
  EXPECT_FALSE(plain[0].frame.has_value());
}

TEST(TreeCsvTest, DetectionErrors) {
  EXPECT_EQ(DetectionError("x,y,axis_x,axis_y\n1,2,0,0\n"),
            "d.csv:1: missing required column 'axis_z' (columns: x,y,axis_x,axis_y)");
  EXPECT_EQ(DetectionError("x,y,axis_x,axis_y,axis_z\n1,2,0,,1\n"),
            "d.csv:2: column 'axis_y': missing while other axis components are given");
  EXPECT_EQ(DetectionError("x,y,score\n1,2,Inf\n"),
            "d.csv:2: column 'score': 'Inf' is not a finite number");
  EXPECT_EQ(DetectionError("frame,x,y\n,1,2\n"),
            "d.csv:2: column 'frame': missing value (required)");
  EXPECT_EQ(CsvErrorOf([] { ParseFramesCsv("x,y\n1,2\n", "f.csv"); }),
            "f.csv:1: missing required column 'frame' (columns: x,y)");
}

TEST(TreeCsvTest, FramesAreGroupedInOrderOfFirstAppearance) {
  const auto frames = ParseFramesCsv("frame,x,y\n5,0,0\n5,1,0\n2,2,0\n5,3,0\n", "f.csv");
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].frame, 5);
  ASSERT_EQ(frames[0].trees.size(), 3u);
  EXPECT_EQ(frames[0].trees[2].position.x(), 3);
  EXPECT_EQ(frames[1].frame, 2);
  EXPECT_EQ(frames[1].trees.size(), 1u);
}

TEST(TreeCsvTest, PosesAreNormalisedAndChecked) {
  const auto poses = ParsePosesCsv(
      "frame,timestamp,x,y,z,qx,qy,qz,qw\n0,1.0,1,2,3,0,0,0.70711,0.70711\n", "p.csv");
  ASSERT_EQ(poses.size(), 1u);
  const algorithms::Pose3& world_from_sensor = poses.at(0);
  EXPECT_TRUE(world_from_sensor.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  // 90 degrees about z: sensor x points along world y.
  EXPECT_TRUE((world_from_sensor.linear() * Eigen::Vector3d::UnitX())
                  .isApprox(Eigen::Vector3d::UnitY(), 1e-9));
  EXPECT_EQ(
      CsvErrorOf([] { ParsePosesCsv("frame,x,y,z,qx,qy,qz,qw\n0,1,2,3,0,0,0,0.5\n", "p.csv"); }),
      "p.csv:2: column 'qw': quaternion norm 0.500000 is not 1");
  EXPECT_EQ(CsvErrorOf([] {
              ParsePosesCsv("frame,x,y,z,qx,qy,qz,qw\n3,1,2,3,0,0,0,1\n3,1,2,3,0,0,0,1\n", "p.csv");
            }),
            "p.csv:3: column 'frame': duplicate frame 3 (lines 2 and 3)");
}

std::vector<MapTreeRow> RoundTrip(const std::vector<MapTreeRow>& rows) {
  std::ostringstream out;
  WriteMapTreesCsv(out, rows);
  return ParseMapTreesCsv(out.str(), "roundtrip.csv");
}

TEST(TreeCsvTest, WriteThenReadIsExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-1e6, 1e6);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const std::vector<std::string> awkward = {
      "plain", "with, comma", "with \"quotes\"", "two\nlines", "NA", "", " padded ", "NaN", "é ü"};
  std::vector<MapTreeRow> rows;
  for (int i = 0; i < 500; ++i) {
    MapTreeRow row;
    if (i % 7 != 0) row.id = i * 3 - 100;
    row.x = coordinate(rng);
    row.y = i == 1 ? std::numeric_limits<double>::min() : coordinate(rng) * 1e-9;
    if (i % 3 != 0) row.z = unit(rng) * 300 - 10;
    if (i % 4 != 0) row.dbh = unit(rng) / 3;
    // A table: a row without a value in a column has it as a null attribute.
    if (i % 2 == 0) {
      row.attributes["species"] = awkward[i % awkward.size()];
    } else {
      row.null_attributes.insert("species");
    }
    if (i % 5 == 0) {
      row.attributes["Height m"] = std::to_string(unit(rng));
    } else {
      row.null_attributes.insert("Height m");
    }
    row.null_attributes.insert("LI");  // unknown in every row: the column still round-trips
    rows.push_back(row);
  }
  EXPECT_EQ(RoundTrip(rows), rows);
  EXPECT_TRUE(RoundTrip({}).empty());
}

TEST(TreeCsvTest, AColumnUnknownInEveryRowIsKept) {
  const auto rows = ParseMapTreesCsv("x,y,LI,Spp\n0,0,NA,41\n1,1,NA,\n", "prf.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].null_attributes, std::set<std::string>{"LI"});
  EXPECT_EQ(rows[1].null_attributes, (std::set<std::string>{"LI", "Spp"}));
  std::ostringstream out;
  WriteMapTreesCsv(out, rows);
  EXPECT_EQ(out.str(), "id,x,y,z,dbh,LI,Spp\n,0,0,,,,41\n,1,1,,,,\n");
}

// Attributes named like a tree column or a dialect's marker (FORTLS keeps its plot `id`, lidR tree
// tops their `Z`) are written as attr_NAME: the file reads back with its tree columns and metres.
TEST(TreeCsvTest, AttributesNamedLikeTreeColumnsAreWrittenWithAPrefix) {
  MapTreeRow row;
  row.x = 1;
  row.y = 2;
  row.dbh = 0.3;
  row.attributes = {{"X_m", "1"}, {"id", "plot7"}, {"h.dist", "2.9"}, {"Z", "23.4"}, {"h", "17"}};
  std::ostringstream out;
  WriteMapTreesCsv(out, {row});
  EXPECT_EQ(out.str(),
            "id,x,y,z,dbh,attr_X_m,attr_Z,h,attr_h.dist,attr_id\n,1,2,,0.3,1,23.4,17,2.9,plot7\n");
  const MapTreeRow back = RoundTrip({row})[0];
  EXPECT_EQ(back.dbh, 0.3);  // h.dist did not make it FORTLS centimetres
  EXPECT_EQ(back.attributes.at("attr_id"), "plot7");
  // Two attributes one column would take: the later one gets a column of its own.
  row.attributes = {{"id", "a"}, {"attr_ID", "b"}, {"Species", "c"}, {"species", "d"}};
  const MapTreeRow renamed = RoundTrip({row})[0];
  EXPECT_EQ(renamed.attributes,
            (std::map<std::string, std::string>{
                {"attr_ID", "b"}, {"id_2", "a"}, {"Species", "c"}, {"attr_species", "d"}}));
}

TEST(TreeCsvTest, WriteRejectsWhatWouldNotReadBack) {
  MapTreeRow row;
  row.id = 4;
  row.y = std::nan("");
  EXPECT_EQ(CsvErrorOf([&] { RoundTrip({row}); }), "cannot write tree #1 (id 4): y is not finite");
}

TEST(TreeCsvTest, WritesToFile) {
  const fs::path path = fs::temp_directory_path() / "forestmap_tree_csv_test.csv";
  MapTreeRow row;
  row.x = 1;
  row.y = 2;
  row.dbh = 0.3;
  WriteMapTreesCsv(path.string(), {row});
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "id,x,y,z,dbh\n,1,2,,0.3\n");
  EXPECT_EQ(ReadMapTreesCsv(path.string()), std::vector<MapTreeRow>{row});
  fs::remove(path);
}

// ---- Real data ----

const fs::path kData = FORESTMAP_SHARED_DATA;

TEST(TreeCsvRealDataTest, EveryStemMapReadsWithItsCountAndRoundTrips) {
  const fs::path dir = kData / "stemmaps";
  if (!fs::exists(dir / "INDEX.csv")) FORESTMAP_SKIP_WITHOUT_DATA() << "no stem maps at " << dir;
  CsvReader index = CsvReader::Open((dir / "INDEX.csv").string());
  ASSERT_EQ(index.header()[0], "name");
  ASSERT_EQ(index.header()[1], "n");
  int maps = 0;
  while (index.Next()) {
    const std::string name(index.fields()[0].text);
    const size_t expected = std::stoul(std::string(index.fields()[1].text));
    SCOPED_TRACE(name);
    const auto rows = ReadMapTreesCsv((dir / (name + ".csv")).string());
    EXPECT_EQ(rows.size(), expected);
    for (const MapTreeRow& row : rows) ASSERT_TRUE(row.id.has_value());
    EXPECT_EQ(RoundTrip(rows), rows);
    ++maps;
  }
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    files += entry.path().extension() == ".csv" && entry.path().filename() != "INDEX.csv";
  }
  EXPECT_EQ(maps, files) << "INDEX.csv should list every stem map";
  EXPECT_GE(maps, 20);
}

TEST(TreeCsvRealDataTest, StemMapMarksBecomeAttributes) {
  const fs::path path = kData / "stemmaps" / "siplab_boreasNP.csv";
  if (!fs::exists(path)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << path;
  const auto rows = ReadMapTreesCsv(path.string());
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(rows[0].id, 1);
  EXPECT_EQ(rows[0].x, 71.6);
  EXPECT_EQ(rows[0].y, -29.92);
  EXPECT_EQ(rows[0].dbh, 0.07);
  EXPECT_EQ(rows[0].attributes.at("height_m"), "8.97");
  EXPECT_EQ(rows[0].attributes.at("species"), "Jack_pine");
}

TEST(TreeCsvRealDataTest, WildV02FramesAndPoses) {
  const fs::path dir = kData / "sequences" / "Wild_V02";
  if (!fs::exists(dir / "trees.csv")) FORESTMAP_SKIP_WITHOUT_DATA() << "no sequence at " << dir;
  const auto frames = ReadFramesCsv((dir / "trees.csv").string());
  ASSERT_EQ(frames.size(), 1375u);
  size_t trees = 0;
  size_t unknown_scores = 0;
  for (const Frame& frame : frames) {
    trees += frame.trees.size();
    for (const auto& tree : frame.trees) {
      unknown_scores += std::isnan(tree.score);
      ASSERT_TRUE(tree.HasAxis());
      ASSERT_TRUE(std::isfinite(tree.dbh));
    }
  }
  EXPECT_EQ(trees, 311130u);
  EXPECT_EQ(unknown_scores, 23u);  // written as "nan" in the file
  EXPECT_EQ(frames[0].frame, 0);
  EXPECT_EQ(frames[0].trees[0].position, Eigen::Vector3d(37.6557, 15.5165, -2.6048));
  // Axes are normalised on reading (the file's are unit to 4 decimals).
  EXPECT_TRUE(frames[0].trees[0].axis.isApprox(Eigen::Vector3d(0.2008, 0.0854, 0.9759).normalized(),
                                               1e-12));

  const auto poses = ReadPosesCsv((dir / "poses.csv").string());
  ASSERT_EQ(poses.size(), 1375u);
  for (const Frame& frame : frames) EXPECT_TRUE(poses.count(frame.frame)) << frame.frame;
  const algorithms::Pose3& world_from_sensor = poses.at(0);
  EXPECT_EQ(world_from_sensor.translation(), Eigen::Vector3d(391.41347, -209.52740, 139.31155));
  const Eigen::Quaterniond q(0.62294, 0.01299, 0.01038, 0.78209);
  EXPECT_TRUE(world_from_sensor.linear().isApprox(q.normalized().toRotationMatrix(), 1e-12));
}

// A survey's ids as field crews write them: 12.0 is 12; text ids (A1, 12a, 1.5) are kept as the
// attribute of the id column's name and in text_id, the trees getting numeric ids when stored.
TEST(TreeCsvTest, TextIdsAreKeptAsAttributes) {
  const std::vector<MapTreeRow> whole =
      ParseMapTreesCsv("id,x,y\n1.0,0,0\n2.00,1,1\n3,2,2\n", "t.csv");
  ASSERT_EQ(whole.size(), 3u);
  EXPECT_EQ(whole[0].id, 1);
  EXPECT_EQ(whole[1].id, 2);
  EXPECT_EQ(whole[2].id, 3);
  EXPECT_TRUE(whole[0].attributes.empty());
  std::ostringstream notes;
  TreeFileOptions options;
  options.notes = &notes;
  const std::vector<MapTreeRow> text =
      ParseMapTreesCsv("tree_id,x,y\n7,0,0\nA1,1,1\n12a,2,2\n,3,3\n1.5,4,4\n", "t.csv", options);
  ASSERT_EQ(text.size(), 5u);
  for (const MapTreeRow& row : text) EXPECT_FALSE(row.id.has_value()) << row;
  EXPECT_EQ(text[0].attributes.at("tree_id"), "7");
  EXPECT_EQ(text[1].attributes.at("tree_id"), "A1");
  EXPECT_EQ(text[1].text_id, "A1");
  EXPECT_EQ(text[2].text_id, "12a");
  EXPECT_FALSE(text[3].text_id.has_value());
  EXPECT_EQ(text[3].null_attributes, std::set<std::string>{"tree_id"});
  EXPECT_EQ(text[4].text_id, "1.5");
  EXPECT_NE(notes.str().find("column 'tree_id' holds ids that are not integers (e.g. '7')"),
            std::string::npos)
      << notes.str();
  EXPECT_EQ(MapError("id,x,y\nA1,0,0\nB2,0,0\nA1,1,1\n"),
            "t.csv:4: column 'id': duplicate tree id A1 (lines 2 and 4)");
  EXPECT_EQ(MapError("id,x,y\n1.0,0,0\n1,1,1\n"),
            "t.csv:3: column 'id': duplicate tree id 1 (lines 2 and 3)");
}

// European spreadsheets (';' with decimal commas) and tab-separated text read as CSV does.
TEST(TreeCsvTest, SemicolonAndTabSeparatedFilesAreRead) {
  const std::vector<MapTreeRow> euro = ParseMapTreesCsv(
      "id;x;y;dbh;species\r\n1;312030,02;5096043,18;0,149;Picea abies\r\n2;-1,5;3;0,3;\"1,5\"\r\n",
      "e.csv");
  ASSERT_EQ(euro.size(), 2u);
  EXPECT_DOUBLE_EQ(euro[0].x, 312030.02);
  EXPECT_DOUBLE_EQ(euro[0].y, 5096043.18);
  EXPECT_DOUBLE_EQ(*euro[0].dbh, 0.149);
  EXPECT_EQ(euro[0].attributes.at("species"), "Picea abies");
  EXPECT_DOUBLE_EQ(euro[1].x, -1.5);
  EXPECT_EQ(euro[1].attributes.at("species"), "1,5");  // quoted: text as it is
  const std::vector<MapTreeRow> tabs =
      ParseMapTreesCsv("id\tx\ty\tdbh\tnote\n1\t10\t20\t0.3\t\n2\t12\t21\t0.25\tok\n", "t.tsv");
  ASSERT_EQ(tabs.size(), 2u);
  EXPECT_DOUBLE_EQ(tabs[1].x, 12);
  EXPECT_DOUBLE_EQ(*tabs[1].dbh, 0.25);
  EXPECT_EQ(tabs[0].null_attributes, std::set<std::string>{"note"});  // empty field kept
  EXPECT_EQ(tabs[1].attributes.at("note"), "ok");
  // A comma file with a ';' in a quoted header name stays a comma file.
  EXPECT_EQ(ParseMapTreesCsv("x,y,\"a;b\"\n1,2,3\n", "c.csv")[0].attributes.at("a;b"), "3");
}

// Files that are no text table say what they are instead of dumping bytes.
TEST(TreeCsvTest, Utf16AndBinaryFilesAreNamed) {
  EXPECT_EQ(MapError(std::string("\xFF\xFEx\0,\0y\0\n\0", 10)),
            "t.csv: UTF-16 text (Excel's \"Unicode text\"): save it as UTF-8 CSV (\"CSV UTF-8\")");
  EXPECT_EQ(MapError(std::string("\xFE\xFF\0x\0,\0y", 9)).substr(0, 20), "t.csv: UTF-16 text (");
  EXPECT_EQ(MapError(std::string("LASF\0\0\x01\0", 8)),
            "t.csv: a LAS point cloud, not a tree table: use `forestmap detect` to find its trees");
  EXPECT_EQ(MapError(std::string("PK\x03\x04\x14\0\x06\0", 8)),
            "t.csv: a zip archive (an .xlsx workbook?), not a text table: save the sheet as CSV");
  EXPECT_EQ(MapError(std::string("\x7F"
                                 "ELF\x02\x01",
                                 6)),
            "t.csv: an executable (ELF), not a text table");
  EXPECT_EQ(MapError(std::string("x,y\n1,\0\x01", 8)),
            "t.csv: binary data (a NUL byte near the start), not a text table");
}

// 3DFin's own text output: no header, blank-separated TH DBH X Y.
TEST(TreeCsvTest, ThreeDfinDbhAndHeightsTableIsRead) {
  const std::string table = "17.234 0.251 12.345 45.678\n15.100  0.180\t14.000 40.000\n\n";
  const std::vector<MapTreeRow> rows = ParseMapTreesCsv(table, "plot_dbh_and_heights.txt");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_DOUBLE_EQ(rows[0].x, 12.345);
  EXPECT_DOUBLE_EQ(rows[0].y, 45.678);
  EXPECT_DOUBLE_EQ(*rows[0].dbh, 0.251);
  EXPECT_EQ(rows[0].attributes.at("TH"), "17.234");
  EXPECT_DOUBLE_EQ(*rows[1].dbh, 0.18);
  EXPECT_EQ(CsvErrorOf([&] { ParseMapTreesCsv(table, "trees.txt"); }),
            "trees.txt: no header row (the first line is numbers): a tree table needs one naming "
            "its columns (x,y,dbh,...); 3DFin's *_dbh_and_heights.txt (TH DBH X Y) is read by "
            "that name");
}

}  // namespace
}  // namespace forestmap::client
