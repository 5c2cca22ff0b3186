// Inventories as delivered: --columns, --dbh-unit, the median-DBH check and the tools' dialects,
// on the real PRF025 field and LiDAR inventories.
#include "client/io/tree_columns.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "client/io/tree_csv.h"
#include "tests/client/io/csv_test_util.h"

namespace forestmap::client {
namespace {

const std::string kPlot = std::string(FORESTMAP_SHARED_DATA) + "/survey_vs_lidar/PRF025/";
constexpr double kTolerance = 1e-9;

using testing_util::CsvErrorOf;

TreeFileOptions FieldOptions() {
  TreeFileOptions options;
  options.columns = ParseColumnMapping("x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree");
  options.dbh_unit = DbhUnit::kCentimetre;
  return options;
}

void SkipWithoutData() {
  if (!std::filesystem::exists(kPlot + "PRF025_Field.csv")) GTEST_SKIP() << "no " << kPlot;
}

TEST(TreeColumnsTest, FieldInventoryReadsAsDeliveredWithColumnsAndUnit) {
  SkipWithoutData();
  const auto rows = ReadMapTreesCsv(kPlot + "PRF025_Field.csv", FieldOptions());
  ASSERT_EQ(rows.size(), 62u);
  // Line 2: "PRF025","1",41,...,DBH 14.9,...,Field_Xpj 312030.0203,Field_Ypj 5096043.185
  EXPECT_EQ(rows[0].id, 1);
  EXPECT_NEAR(rows[0].x, 312030.0203, kTolerance);
  EXPECT_NEAR(rows[0].y, 5096043.185, kTolerance);
  ASSERT_TRUE(rows[0].dbh.has_value());
  EXPECT_NEAR(*rows[0].dbh, 0.149, kTolerance);
  // Every other column is an attribute, under its own name; NA is a null attribute (LI, LO: NA
  // in every row, BT in all but one), so the column is kept.
  EXPECT_EQ(rows[0].attributes.at("Spp"), "41");
  EXPECT_EQ(rows[0].attributes.at("Plot"), "PRF025");
  EXPECT_EQ(rows[0].attributes.at("Field_X"), "0.502574283");
  EXPECT_EQ(rows[0].attributes.count("LI"), 0u);
  for (const auto& row : rows) {
    EXPECT_EQ(row.null_attributes.count("LI"), 1u) << row;
    EXPECT_EQ(row.null_attributes.count("LO"), 1u) << row;
    EXPECT_EQ(row.attributes.size() + row.null_attributes.size(), 17u) << row;
  }
  EXPECT_EQ(rows[0].attributes.count("DBH"), 0u);
  EXPECT_EQ(rows[0].attributes.count("Tree"), 0u);
}

TEST(TreeColumnsTest, CentimetreDbhWithoutUnitIsRefusedNamingFileAndColumn) {
  SkipWithoutData();
  TreeFileOptions options = FieldOptions();
  options.dbh_unit.reset();
  const std::string error =
      CsvErrorOf([&] { ReadMapTreesCsv(kPlot + "PRF025_Field.csv", options); });
  EXPECT_NE(error.find("PRF025_Field.csv"), std::string::npos) << error;
  EXPECT_NE(error.find("column 'DBH'"), std::string::npos) << error;
  EXPECT_NE(error.find("--dbh-unit cm"), std::string::npos) << error;
}

TEST(TreeColumnsTest, UnmappedAndMissingColumnsAreNamed) {
  SkipWithoutData();
  const std::string path = kPlot + "PRF025_Field.csv";
  const std::string unmapped = CsvErrorOf([&] { ReadMapTreesCsv(path); });
  EXPECT_NE(unmapped.find("PRF025_Field.csv:1: missing required column 'x'"), std::string::npos)
      << unmapped;
  TreeFileOptions options = FieldOptions();
  options.columns["x"] = "Field_Xpjj";
  const std::string wrong = CsvErrorOf([&] { ReadMapTreesCsv(path, options); });
  EXPECT_NE(wrong.find("PRF025_Field.csv:1: --columns x=Field_Xpjj: no column 'Field_Xpjj'"),
            std::string::npos)
      << wrong;
}

TEST(TreeColumnsTest, LidrOutputReadsWithoutMapping) {
  SkipWithoutData();
  const auto rows = ReadMapTreesCsv(kPlot + "PRF025_Lidar.csv");
  ASSERT_EQ(rows.size(), 93u);
  EXPECT_EQ(rows[0].id, 5);  // treeID
  EXPECT_NEAR(rows[0].x, 312028.287811509, kTolerance);
  EXPECT_NEAR(*rows[0].z, 185.783607597131, kTolerance);
  EXPECT_NEAR(*rows[0].dbh, 0.0401739196739485, kTolerance);
  EXPECT_EQ(rows[0].attributes.at("plotID"), "PRF025");
}

TEST(TreeColumnsTest, FortlsTreeListUsesTreeAsIdAndCentimetres) {
  const auto rows = ParseMapTreesCsv(
      "id,file,tree,x,y,phi,h.dist,dbh,h\nplot7,p7.las,3,1.5,2.5,0.1,2.9,23.4,17\n", "f.csv");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].id, 3);
  EXPECT_NEAR(*rows[0].dbh, 0.234, kTolerance);
  EXPECT_EQ(rows[0].attributes.at("id"), "plot7");
}

// TreeLoc++'s TreeManagerState_N.csv (the header and two rows of its Oxford_Evo data, the
// second tree not reconstructed: no dbh, only dbh_approximation).
TEST(TreeColumnsTest, TreeLocTreeStateReadsWithoutMapping) {
  const std::string header =
      "axis_00,axis_01,axis_02,axis_10,axis_11,axis_12,axis_20,axis_21,axis_22,location_x,"
      "location_y,location_z,dbh,dbh_approximation,score,reconstructed,number_clusters\n";
  const auto rows = ParseMapTreesCsv(
      header +
          "-0.905,-0.424,-0.024,0.425,-0.904,-0.048,-0.001,-0.054,0.999,13.3553,-12.7387,-2.6658,"
          "0.1653,0.1459,0.5946,True,4\n"
          "-0.296,0.955,-0.005,-0.955,-0.296,-0.023,-0.023,-0.002,1.0,23.7208,1.2068,-1.4286,,"
          "0.2218,1.0,False,1\n",
      "TreeManagerState_0.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_FALSE(rows[0].id.has_value());  // no id column: the server assigns ids
  EXPECT_NEAR(rows[0].x, 13.3553, kTolerance);
  EXPECT_NEAR(rows[0].y, -12.7387, kTolerance);
  EXPECT_NEAR(*rows[0].z, -2.6658, kTolerance);
  EXPECT_NEAR(*rows[0].dbh, 0.1653, kTolerance);  // dbh, in m
  EXPECT_NEAR(*rows[1].dbh, 0.2218, kTolerance);  // dbh_approximation where dbh is empty
  EXPECT_EQ(rows[0].attributes.at("reconstructed"), "True");
  EXPECT_EQ(rows[0].attributes.at("axis_22"), "0.999");
  EXPECT_EQ(rows[0].attributes.count("location_x"), 0u);
}

// lidR's locate_trees: treeID, Z (the tree-top height) and the point; no DBH.
TEST(TreeColumnsTest, LidrTreeTopsKeepTheirHeightAsAnAttribute) {
  const auto rows = ParseMapTreesCsv("X,Y,treeID,Z\n481260.5,3812981.2,1,23.4\n", "ttops.csv");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].id, 1);
  EXPECT_NEAR(rows[0].x, 481260.5, kTolerance);
  EXPECT_FALSE(rows[0].z.has_value());  // a tree top is no stem base
  EXPECT_EQ(rows[0].attributes.at("Z"), "23.4");
  EXPECT_FALSE(rows[0].dbh.has_value());
  // --columns z=Z says otherwise.
  TreeFileOptions options;
  options.columns = {{"z", "Z"}};
  EXPECT_NEAR(*ParseMapTreesCsv("X,Y,treeID,Z\n1,2,1,23.4\n", "t.csv", options)[0].z, 23.4,
              kTolerance);
}

// 3DFin's tree table (Tree Analysis / dbh_and_heights saved as CSV: tree names in an unnamed
// first column, DBH in m).
TEST(TreeColumnsTest, ThreeDFinTreeTableReadsWithoutMapping) {
  const auto rows = ParseMapTreesCsv(
      ",DBH,Normal_Section_Area,Tree_Height,Crown_Height,Stem_Volume,X,Y\n"
      "T1,0.254,0.0507,18.2,9.1,0.41,451203.12,4801122.85\n",
      "3dfin.csv");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_NEAR(*rows[0].dbh, 0.254, kTolerance);
  EXPECT_NEAR(rows[0].x, 451203.12, kTolerance);
  EXPECT_EQ(rows[0].attributes.at("Tree_Height"), "18.2");
  EXPECT_EQ(rows[0].attributes.count(""), 0u);  // the unnamed tree-name column is ignored
  const auto legacy = ParseMapTreesCsv(",TH,DBH,X,Y\nT1,18.2,0.254,1.5,2.5\n", "3dfin.csv");
  EXPECT_NEAR(*legacy[0].dbh, 0.254, kTolerance);
  EXPECT_EQ(legacy[0].attributes.at("TH"), "18.2");
}

TEST(TreeColumnsTest, UnitSuffixAndExplicitUnit) {
  EXPECT_NEAR(*ParseMapTreesCsv("x,y,dbh_cm\n1,2,31\n", "a.csv")[0].dbh, 0.31, kTolerance);
  EXPECT_NEAR(*ParseMapTreesCsv("x,y,DBH_mm\n1,2,310\n", "a.csv")[0].dbh, 0.31, kTolerance);
  TreeFileOptions options;
  options.dbh_unit = DbhUnit::kMillimetre;
  EXPECT_NEAR(*ParseMapTreesCsv("x,y,dbh\n1,2,310\n", "a.csv", options)[0].dbh, 0.31, kTolerance);
  // A mapped column keeps a column that would also give `x` as an attribute.
  options = {};
  options.columns = {{"x", "E"}};
  const auto rows = ParseMapTreesCsv("x,E,y\n9,1,2\n", "a.csv", options);
  EXPECT_EQ(rows[0].x, 1);
  EXPECT_EQ(rows[0].attributes.at("x"), "9");
}

TEST(TreeColumnsTest, OptionTextErrorsSayWhatIsWrong) {
  EXPECT_THROW(ParseColumnMapping("x"), std::invalid_argument);
  EXPECT_THROW(ParseColumnMapping("height=Ht"), std::invalid_argument);
  EXPECT_THROW(ParseColumnMapping("x=A,x=B"), std::invalid_argument);
  EXPECT_THROW(ParseDbhUnit("inch"), std::invalid_argument);  // "in" is the unit
  EXPECT_EQ(ParseColumnMapping(" X = Field_Xpj ,dbh=DBH").at("x"), "Field_Xpj");
}

template <typename Parse>
std::string InvalidArgumentOf(Parse parse) {
  try {
    parse();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

// One column for two tree columns is named as such, and every message names the flag given.
TEST(TreeColumnsTest, ErrorsNameTheFlagAndAColumnMappedTwice) {
  EXPECT_EQ(InvalidArgumentOf([] { ParseColumnMapping("x=A,y=a"); }),
            "--columns: the column 'a' is mapped twice (x=A and y=a): each tree column needs its "
            "own");
  EXPECT_EQ(InvalidArgumentOf([] { ParseColumnMapping("q=A", "--reference-columns"); }),
            "--reference-columns: 'q' is not a tree column (x, y, z, dbh, id)");
  EXPECT_EQ(InvalidArgumentOf([] { ParseDbhUnit("yd", "--reference-dbh-unit"); }),
            "--reference-dbh-unit: 'yd' is not one of m, cm, mm, in");
  TreeFileOptions options;
  options.columns_flag = "--reference-columns";
  options.columns = {{"dbh", "DBHX"}};
  EXPECT_EQ(CsvErrorOf([&] { ParseMapTreesCsv("x,y,dbh\n1,2,0.3\n", "r.csv", options); }),
            "r.csv:1: --reference-columns dbh=DBHX: no column 'DBHX' (columns: x,y,dbh)");
}

// Inches: --dbh-unit in and a dbh_in column (US inventories).
TEST(TreeColumnsTest, InchesAreADbhUnit) {
  EXPECT_EQ(ParseDbhUnit("in"), DbhUnit::kInch);
  const auto rows = ParseMapTreesCsv("id,x,y,dbh_in\n1,10,20,12\n2,12,21,10\n", "a.csv");
  ASSERT_TRUE(rows[0].dbh.has_value());
  EXPECT_NEAR(*rows[0].dbh, 12 * 0.0254, kTolerance);
  EXPECT_TRUE(rows[0].attributes.empty());
  TreeFileOptions options;
  options.dbh_unit = DbhUnit::kInch;
  EXPECT_NEAR(*ParseMapTreesCsv("x,y,dbh\n1,2,10\n", "a.csv", options)[0].dbh, 0.254, kTolerance);
}

// A --dbh-unit that contradicts the column's name, and a median under 1 cm (metres read as cm),
// are refused naming column, unit and flag.
TEST(TreeColumnsTest, ImplausibleDbhUnitsAreRefused) {
  TreeFileOptions options;
  options.dbh_unit = DbhUnit::kMillimetre;
  EXPECT_EQ(CsvErrorOf([&] { ParseMapTreesCsv("x,y,dbh_cm\n1,2,31\n", "a.csv", options); }),
            "a.csv:1: column 'dbh_cm' is in cm by its name, but --dbh-unit says mm: drop "
            "--dbh-unit or rename the column");
  options.dbh_unit = DbhUnit::kCentimetre;
  EXPECT_NEAR(*ParseMapTreesCsv("x,y,dbh_cm\n1,2,31\n", "a.csv", options)[0].dbh, 0.31,
              kTolerance);  // the same unit twice is fine
  EXPECT_EQ(
      CsvErrorOf(
          [&] { ParseMapTreesCsv("x,y,dbh\n1,2,0.31\n3,4,0.25\n5,6,0.4\n", "a.csv", options); }),
      "a.csv: column 'dbh': the median DBH is 0.0031 m read in cm (under 1 cm: no inventory of "
      "trees); if the column is in metres, drop --dbh-unit or give --dbh-unit m");
}

}  // namespace
}  // namespace forestmap::client
