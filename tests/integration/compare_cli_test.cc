// `forestmap compare` through the built binary on small inventories written here: figures over
// nothing, the unknown-DBH row, unlinked trees, text ids, visible trees, --register in the JSON,
// and messages that name the flag given.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>

#include "tests/cli_run.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;

using Result = testing_util::CliResult;
using testing_util::ReadWholeFile;

class CompareCliTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing_util::FreshTestFolder("forestmap_compare_test"); }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path Write(const std::string& name, const std::string& content) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << content;
    return path;
  }
  Result Compare(const std::string& args) {
    return testing_util::RunCapturing(
        "cd '" + dir_.string() + "' && '" FORESTMAP_CLI_PATH "' compare " + args, dir_);
  }

  fs::path dir_;
};

TEST_F(CompareCliTest, NothingMeasuredIsADashAndNullNotZero) {
  Write("d.csv", "id,x,y,dbh\n1,100,100,0.3\n2,200,200,0.2\n");
  Write("r.csv", "id,x,y,dbh\n1,0,0,0.3\n");
  Write("empty.csv", "id,x,y,dbh\n");
  const Result table = Compare("d.csv --reference r.csv");
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("position RMSE    - (no pairs)"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("DBH RMSE         - (no pairs with both DBHs)"), std::string::npos);
  EXPECT_EQ(table.out.find("0.000 m"), std::string::npos) << table.out;
  const Result json = Compare("d.csv --reference r.csv --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const nlohmann::json r = nlohmann::json::parse(json.out);
  EXPECT_TRUE(r["position_rmse_m"].is_null());
  EXPECT_TRUE(r["bias_x_m"].is_null());
  EXPECT_TRUE(r["dbh_rmse_m"].is_null());
  EXPECT_EQ(r["completeness"], 0.0);  // one reference tree, not found: a measurement
  const Result empty = Compare("d.csv --reference empty.csv");
  EXPECT_NE(empty.out.find("completeness     - (no reference trees)"), std::string::npos)
      << empty.out;
  EXPECT_TRUE(
      nlohmann::json::parse(Compare("d.csv --reference empty.csv --json").out)["completeness"]
          .is_null());
}

TEST_F(CompareCliTest, UnknownDbhRowAndUnlinkedTreesWithTextIds) {
  Write("d.csv", "id,x,y,dbh\nD1,0.1,0,0.31\nD2,10,0,0.2\nD3,50,50,0.2\n");
  Write("r.csv", "tree_id,x,y,dbh_cm\nA1,0,0,30\nA2,10,0,NA\nB-7,20,0,NA\n");
  const Result table =
      Compare("d.csv --reference r.csv --out links.csv --out-unlinked unlinked.csv");
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("  unknown DBH       2       1     50.0%"), std::string::npos)
      << table.out;
  EXPECT_NE(table.err.find("column 'tree_id' holds ids that are not integers (e.g. 'A1')"),
            std::string::npos)
      << table.err;
  const std::string links = ReadWholeFile(dir_ / "links.csv");
  EXPECT_NE(links.find("\nD1,A1,0.1000,0.0000,0.0000,0.0000,0.1000,"), std::string::npos) << links;
  EXPECT_NE(links.find("\nD2,A2,"), std::string::npos) << links;
  EXPECT_EQ(ReadWholeFile(dir_ / "unlinked.csv"),
            "status,id,x,y,dbh_m\nmissed,B-7,20.0000,0.0000,\n"
            "commission,D3,50.0000,50.0000,0.2000\n");
  const nlohmann::json r = nlohmann::json::parse(Compare("d.csv --reference r.csv --json").out);
  int classified = 0;
  for (const auto& c : r["omission_by_dbh"]) classified += c["reference_trees"].get<int>();
  EXPECT_EQ(classified, 3);  // every reference tree is in a row, unknown DBH included
  EXPECT_TRUE(r["omission_by_dbh"].back()["min_dbh_m"].is_null());
}

TEST_F(CompareCliTest, CompletenessOverVisibleReferenceTrees) {
  Write("d.csv", "x,y\n0,0\n10,0\n");
  Write("truth.csv",
        "tree_id,x,y,dbh,visible\n0,0,0,0.2,1\n1,10,0,0.2,1\n2,20,0,0.2,0\n"
        "3,30,0,0.2,0\n");
  const Result table = Compare("d.csv --reference truth.csv");
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("completeness     50.0 %"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("  of visible     100.0 % (2 of 2 reference trees marked visible=1)"),
            std::string::npos)
      << table.out;
  const nlohmann::json r = nlohmann::json::parse(Compare("d.csv --reference truth.csv --json").out);
  EXPECT_EQ(r["visible_reference_trees"], 2);
  EXPECT_EQ(r["visible_completeness"], 1.0);
}

// A random stand and the same stand rotated and shifted: --register puts the transform in JSON.
TEST_F(CompareCliTest, RegisterTransformIsInTheJson) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(0, 40);
  std::ostringstream reference, detected, other;
  reference << "id,x,y,dbh\n";
  detected << "id,x,y,dbh\n";
  other << "id,x,y,dbh\n";
  const double angle = 0.5;
  for (int i = 0; i < 60; ++i) {
    const double x = coordinate(rng), y = coordinate(rng), dbh = 0.15 + 0.005 * (i % 30);
    reference << i << ',' << x << ',' << y << ',' << dbh << '\n';
    detected << i << ',' << std::cos(angle) * x - std::sin(angle) * y + 100 << ','
             << std::sin(angle) * x + std::cos(angle) * y - 50 << ',' << dbh << '\n';
    other << i << ',' << coordinate(rng) << ',' << coordinate(rng) << ',' << dbh << '\n';
  }
  Write("r.csv", reference.str());
  Write("d.csv", detected.str());
  const Result json =
      Compare("d.csv --reference r.csv --register --json --registered-out moved.csv");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const nlohmann::json r = nlohmann::json::parse(json.out);
  ASSERT_TRUE(r.contains("registration")) << json.out;
  const nlohmann::json& t = r["registration"];
  EXPECT_NEAR(t["rotation_deg"].get<double>(), -angle * 180 / M_PI, 0.1);
  EXPECT_EQ(r["linked"], 60);
  // The shift about the reference's centre c is what the transform does there: T(c) - c, with
  // T(d) = R(-angle) (d - (100, -50)) (the detections are the reference turned by `angle` about
  // the origin, then moved by (100, -50)).
  const double cx = t["centre_x_m"], cy = t["centre_y_m"];
  EXPECT_GT(cx, 10);
  EXPECT_LT(cx, 30);
  const double qx = cx - 100, qy = cy + 50;
  const double tx = std::cos(angle) * qx + std::sin(angle) * qy;
  const double ty = -std::sin(angle) * qx + std::cos(angle) * qy;
  EXPECT_NEAR(t["shift_x_m"].get<double>(), tx - cx, 0.05);
  EXPECT_NEAR(t["shift_y_m"].get<double>(), ty - cy, 0.05);
  EXPECT_NE(json.err.find("about the reference's centre"), std::string::npos) << json.err;
  // The registered detections lie on the reference's trees, with their own columns.
  std::ifstream moved(dir_ / "moved.csv");
  std::ifstream truth(dir_ / "r.csv");
  std::string header, line, expected;
  std::getline(moved, header);
  std::getline(truth, expected);
  EXPECT_EQ(header, "id,x,y,z,dbh");
  int rows = 0;
  while (std::getline(moved, line) && std::getline(truth, expected)) {
    double id, x, y, ex, ey, ignored;
    char c;
    std::istringstream(line) >> id >> c >> x >> c >> y;
    std::istringstream(expected) >> ignored >> c >> ex >> c >> ey;
    EXPECT_NEAR(x, ex, 0.05) << line;
    EXPECT_NEAR(y, ey, 0.05) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 60);
  EXPECT_NE(Compare("d.csv --reference r.csv --registered-out m.csv").err.find("needs --register"),
            std::string::npos);
}

TEST_F(CompareCliTest, MessagesNameTheFlagGivenAndAreShort) {
  Write("d.csv", "id,x,y,dbh\n1,0,0,0.3\n");
  Write("r.csv", "id,x,y,dbh_cm\n1,0,0,30\n");
  const auto error = [&](const std::string& args) {
    const Result result = Compare(args);
    EXPECT_NE(result.exit_code, 0) << args;
    return result.err;
  };
  EXPECT_EQ(error("d.csv --reference r.csv --reference-dbh-unit yd"),
            "forestmap: error: --reference-dbh-unit: 'yd' is not one of m, cm, mm, in\n");
  EXPECT_EQ(error("d.csv --reference r.csv --reference-dbh-unit mm"),
            "forestmap: error: r.csv:1: column 'dbh_cm' is in cm by its name, but "
            "--reference-dbh-unit says mm: drop --reference-dbh-unit or rename the column\n");
  EXPECT_EQ(error("d.csv --reference r.csv --reference-columns dbh=Q"),
            "forestmap: error: r.csv:1: --reference-columns dbh=Q: no column 'Q' (columns: "
            "id,x,y,dbh_cm)\n");
  EXPECT_EQ(error("d.csv --reference r.csv --columns x=A,y=A"),
            "forestmap: error: --columns: the column 'A' is mapped twice (x=A and y=A): each "
            "tree column needs its own\n");
  const std::string zero = error("d.csv --reference r.csv --link-distance 0");
  EXPECT_NE(zero.find("--link-distance: 0 m is too small: a link distance is at least 0.01 m"),
            std::string::npos)
      << zero;
  EXPECT_LT(zero.size(), 160u) << zero;
  EXPECT_NE(error("d.csv --reference r.csv --dbh-class 0.0001")
                .find("--dbh-class: 0.0001 m is too small: a DBH class is at least 0.01 m"),
            std::string::npos);
  // Classes of 2.5 cm are labelled with their decimals.
  EXPECT_NE(Compare("d.csv --reference r.csv --dbh-class 0.025").out.find("  30.0-32.5"),
            std::string::npos);
}

TEST_F(CompareCliTest, FailedRegistrationSpeaksOfTwoInventories) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coordinate(0, 40);
  std::ostringstream a, b;
  a << "x,y\n";
  b << "x,y\n";
  for (int i = 0; i < 40; ++i) {
    a << coordinate(rng) << ',' << coordinate(rng) << '\n';
    b << coordinate(rng) << ',' << coordinate(rng) << '\n';
  }
  Write("a.csv", a.str());
  Write("b.csv", b.str());
  const Result result = Compare("a.csv --reference b.csv --register");
  ASSERT_NE(result.exit_code, 0) << result.out;
  EXPECT_NE(result.err.find("--register: the detections could not be placed in the reference"),
            std::string::npos)
      << result.err;
  EXPECT_EQ(result.err.find("drone"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("do the two inventories cover the same trees"), std::string::npos);
}

}  // namespace
}  // namespace forestmap
