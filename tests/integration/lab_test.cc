// Runs the built `forestmap-lab` (FORESTMAP_LAB_PATH) as a user would, and `forestmap`
// (FORESTMAP_CLI_PATH) on what the lab's simulator writes.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "client/io/tree_csv.h"
#include "tests/cli_run.h"
#include "tests/client/fake_forestmap_server.h"
#include "tests/shared_data.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;
using testing_util::CliResult;

bool StartsWith(const std::string& text, const std::string& prefix) {
  return text.rfind(prefix, 0) == 0;
}

class LabTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing_util::FreshTestFolder("forestmap_lab_test"); }
  void TearDown() override { fs::remove_all(dir_); }

  // `forestmap-lab ARGS` and `forestmap ARGS` through the shell (ARGS are shell words), with
  // FORESTMAP_SERVER unset.
  CliResult Lab(const std::string& args) { return Run(FORESTMAP_LAB_PATH, args); }
  CliResult Cli(const std::string& args) { return Run(FORESTMAP_CLI_PATH, args); }

  fs::path dir_;

 private:
  CliResult Run(const std::string& program, const std::string& args) {
    return testing_util::RunCapturing("env -u FORESTMAP_SERVER '" + program + "' " + args, dir_);
  }
};

TEST_F(LabTest, HelpExitsZeroForEveryCommand) {
  const CliResult top = Lab("--help");
  EXPECT_EQ(top.exit_code, 0);
  EXPECT_NE(top.out.find("--server"), std::string::npos);
  for (const char* command : {"simulate", "bench-reloc", "bench-mapping", "bench-changes",
                              "bench-server", "bench-load", "demo-data"}) {
    SCOPED_TRACE(command);
    const CliResult result = Lab(std::string(command) + " --help");
    EXPECT_EQ(result.exit_code, 0);
    EXPECT_NE(result.out.find("Usage: forestmap-lab " + std::string(command)), std::string::npos)
        << result.out;
  }
}

TEST_F(LabTest, InvalidCommandLinesExitTwoWithAMessage) {
  for (const char* args : {"", "relocalize m --trees a.csv", "simulate --bogus",
                           "bench-changes --map /dev/null --frames /dev/null"}) {
    SCOPED_TRACE(args);
    const CliResult result = Lab(args);
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_TRUE(StartsWith(result.err, "forestmap-lab: error: ")) << result.err;
    EXPECT_TRUE(result.out.empty());
  }
}

// The thin client's path: a simulated LiDAR scan in, trunks detected here, only trees sent.
TEST_F(LabTest, RelocalizeScanSendsTheTrunksItDetects) {
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  ASSERT_EQ(Cli(s + "map create m").exit_code, 0);
  const CliResult simulated = Lab("simulate --generate 2000 --pose 60,60,3,30 --no-body --out '" +
                                  (dir_ / "sim").string() + "'");
  ASSERT_EQ(simulated.exit_code, 0) << simulated.err;

  const CliResult result =
      Cli(s + "relocalize m --scan '" + (dir_ / "sim" / "scan_000.pcd").string() + "'");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.err.find("trees detected in"), std::string::npos) << result.err;
  EXPECT_EQ(nlohmann::json::parse(result.out)["status"], "localized");  // the fake's answer
  // Every tree sent is one of the simulator's trunks, in the sensor frame.
  const v1::RelocalizeRequest& sent = server.service().last_relocalize;
  EXPECT_GE(sent.trees_size(), 5);
  std::vector<Eigen::Vector2d> truth;
  for (const MapTreeRow& row : ReadMapTreesCsv((dir_ / "sim" / "scan_000_truth.csv").string())) {
    truth.push_back({row.x, row.y});
  }
  int near_truth = 0;
  for (const v1::DetectedTree& tree : sent.trees()) {
    const Eigen::Vector2d p(tree.position().x(), tree.position().y());
    double best = 1e9;
    for (const Eigen::Vector2d& t : truth) best = std::min(best, (t - p).norm());
    near_truth += best < 0.3;
  }
  EXPECT_GE(near_truth, sent.trees_size() * 9 / 10);

  const CliResult missing = Cli(s + "relocalize m --scan /no/such/scan.pcd");
  EXPECT_EQ(missing.exit_code, 2);
  const fs::path bad = dir_ / "bad.pcd";
  std::ofstream(bad) << "not a point cloud";
  const CliResult not_a_scan = Cli(s + "relocalize m --scan '" + bad.string() + "'");
  EXPECT_EQ(not_a_scan.exit_code, 1);
  EXPECT_TRUE(StartsWith(not_a_scan.err, "forestmap: error: ")) << not_a_scan.err;
}

// Scan to pose, the whole thin-client path in process: simulated LiDAR scans of the real longleaf
// stem map -> trunk detection -> relocalization, scored against the simulator's poses.
TEST_F(LabTest, SimulatedScansOfARealStemMapRelocalize) {
  const std::string stemmap =
      std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/spatstat_longleaf.csv";
  if (!fs::exists(stemmap)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << stemmap;
  const std::string dir = (dir_ / "scans").string();
  const CliResult simulated =
      Lab("simulate --map '" + stemmap + "' --random-poses 40 --scanner os1-64 --seed 7 --out '" +
          dir + "'");
  ASSERT_EQ(simulated.exit_code, 0) << simulated.err;
  const CliResult bench =
      Lab("bench-reloc --map '" + dir + "/map.csv' --scans '" + dir + "' --within 0.3 --json");
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  // The index build says so before it starts and when it is done (seconds on a large map).
  const size_t building = bench.err.find("bench-reloc: building the index of ");
  EXPECT_NE(building, std::string::npos) << bench.err;
  const size_t built = bench.err.find("bench-reloc: index built");
  EXPECT_TRUE(built != std::string::npos && built > building) << bench.err;
  const auto report = nlohmann::json::parse(bench.out);
  EXPECT_EQ(report["frames"], 40);
  EXPECT_EQ(report["wrong"], 0);
  // Floor at today's level (200 such scans: 77% within 0.3 m; the bar is 98%).
  EXPECT_GE(report["localized_within_rate"].get<double>(), 0.65) << bench.out;
}

// A stem map's simulated future observed into it: what is felled goes, what stands stays; with
// nothing changed, nothing goes.
TEST_F(LabTest, BenchChangesRemovesFelledTreesOnly) {
  const std::string stemmap = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/spatstat_waka.csv";
  if (!fs::exists(stemmap)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << stemmap;
  const CliResult changed =
      Lab("bench-changes --map '" + stemmap + "' --clear-cut 0.1 --reloc-views 0 --json");
  ASSERT_EQ(changed.exit_code, 0) << changed.err;
  const auto report = nlohmann::json::parse(changed.out);
  EXPECT_GT(report["felled"].get<int>(), 150);
  EXPECT_GE(report["felled_removed"].get<double>(), 0.9) << changed.out;
  EXPECT_EQ(report["live_removed_count"], 0) << changed.out;
  const CliResult unchanged = Lab("bench-changes --map '" + stemmap +
                                  "' --felled 0 --clear-cut 0 --ingrowth 0 --reloc-views 0 --json");
  ASSERT_EQ(unchanged.exit_code, 0) << unchanged.err;
  const auto same = nlohmann::json::parse(unchanged.out);
  EXPECT_EQ(same["felled"], 0);
  EXPECT_EQ(same["live_removed_count"], 0) << unchanged.out;
}

}  // namespace
}  // namespace forestmap::client
