// Trunk detection on real clouds (../shared/data/scans):
//  - treescope_trunk_slices: 13 trunk slices (1.1-1.5 m above ground, no ground points) from a
//    mobile Ouster scan, against field-measured DBH; one at a time and all merged into one cloud;
//  - spanner_ponderosa: the mobile (MLS) and drone (UAS) clips of one plot, whose stems must agree.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>

#include "algorithms/detection/trunk_detection.h"
#include "client/io/csv_reader.h"
#include "client/io/scan_io.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

const std::string kScans = std::string(FORESTMAP_SHARED_DATA) + "/scans/";
const std::string kSlices = kScans + "treescope_trunk_slices/";
constexpr double kDbhRmse = 0.020;      // m, against field calipers
constexpr double kDbhBias = 0.007;      // m
constexpr double kSliceMatch = 0.10;    // m, detection to the slice's centroid
constexpr double kClipMatch = 0.5;      // m, MLS stem to UAS stem after the clip offset
constexpr double kClipPosition = 0.15;  // m, median
constexpr double kClipDbh = 0.03;       // m, median

// Merged clouds: no sensor at the origin, no drone body.
TrunkDetectionOptions MultiViewOptions() {
  TrunkDetectionOptions options;
  options.filter.self_radius = 0;
  options.stem.sensor_at_origin = false;
  return options;
}

struct Slice {
  std::string file;
  double field_dbh = 0;
  PointCloud cloud;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
};

std::vector<Slice> ReadSlices() {
  std::vector<Slice> slices;
  client::CsvReader reader = client::CsvReader::Open(kSlices + "reference.csv");
  const auto& header = reader.header();
  const size_t file_column = std::find(header.begin(), header.end(), "file") - header.begin();
  const size_t dbh_column = std::find(header.begin(), header.end(), "field_dbh_m") - header.begin();
  EXPECT_LT(dbh_column, header.size());
  while (reader.Next()) {
    Slice slice;
    slice.file = std::string(reader.fields().at(file_column).text);
    slice.field_dbh = std::stod(std::string(reader.fields().at(dbh_column).text));
    slice.cloud = client::ReadScan(kSlices + slice.file);
    for (const Eigen::Vector3f& p : slice.cloud.points)
      slice.centroid += p.head<2>().cast<double>();
    slice.centroid /= static_cast<double>(slice.cloud.size());
    slices.push_back(std::move(slice));
  }
  return slices;
}

class TrunkSlicesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kSlices + "reference.csv")) {
      FORESTMAP_SKIP_WITHOUT_DATA() << "no trunk slices at " << kSlices;
    }
    slices_ = ReadSlices();
  }
  std::vector<Slice> slices_;
};

TEST_F(TrunkSlicesTest, DbhAgainstFieldCalipers) {
  ASSERT_EQ(slices_.size(), 13u);
  double sum = 0, sum2 = 0;
  for (const Slice& slice : slices_) {
    const TrunkDetectionResult result = DetectTrunks(slice.cloud, MultiViewOptions());
    EXPECT_FALSE(result.ground_known) << slice.file;
    ASSERT_EQ(result.trees.size(), 1u) << slice.file;
    const DetectedTrunk& trunk = result.trees[0];
    EXPECT_FALSE(trunk.ground_known);
    EXPECT_NEAR(trunk.tree.position.z(), 1.1, 0.02) << "the lowest stem point seen";
    const double error = trunk.tree.dbh - slice.field_dbh;
    std::cout << slice.file << ": field " << slice.field_dbh << " m, detected " << trunk.tree.dbh
              << " m, error " << error * 100 << " cm" << std::endl;
    sum += error;
    sum2 += error * error;
  }
  const double bias = sum / slices_.size(), rmse = std::sqrt(sum2 / slices_.size());
  std::cout << "DBH vs field: rmse " << rmse * 100 << " cm, bias " << bias * 100 << " cm"
            << std::endl;
  EXPECT_LE(rmse, kDbhRmse);
  EXPECT_LE(std::abs(bias), kDbhBias);
}

TEST_F(TrunkSlicesTest, AllThirteenInOneCloudAndNoFalseStems) {
  PointCloud merged;
  for (const Slice& slice : slices_) {
    merged.points.insert(merged.points.end(), slice.cloud.points.begin(), slice.cloud.points.end());
  }
  merged.width = static_cast<uint32_t>(merged.points.size());
  const TrunkDetectionResult result = DetectTrunks(merged, MultiViewOptions());
  EXPECT_FALSE(result.ground_known);
  EXPECT_EQ(result.trees.size(), slices_.size());
  // Each slice is found once, where it is found alone (its centroid is only near the centre:
  // the rings are not complete).
  for (const Slice& slice : slices_) {
    const TrunkDetectionResult alone = DetectTrunks(slice.cloud, MultiViewOptions());
    ASSERT_EQ(alone.trees.size(), 1u);
    int matches = 0;
    for (const DetectedTrunk& trunk : result.trees) {
      const Eigen::Vector2d at = trunk.breast_height_point.head<2>();
      if ((at - slice.centroid).norm() > kSliceMatch + 0.5 * trunk.tree.dbh) continue;
      ++matches;
      EXPECT_NEAR((at - alone.trees[0].breast_height_point.head<2>()).norm(), 0, 0.01);
      EXPECT_NEAR(trunk.tree.dbh, alone.trees[0].tree.dbh, 0.005);
    }
    EXPECT_EQ(matches, 1) << slice.file;
  }
}

// The drone clip is offset from the mobile clip by about 0.59 m in x (a co-registration offset of
// the data set, seen on every stem pair); the test removes the median offset of the pairs found
// within 1 m, then requires agreement of the stems found in both.
TEST(PonderosaClipsTest, MobileAndDroneStemsAgree) {
  const std::string dir = kScans + "spanner_ponderosa/";
  if (!std::filesystem::exists(dir + "MLS_Clip.pcd"))
    FORESTMAP_SKIP_WITHOUT_DATA() << "no clips at " << dir;
  const PointCloud mls = client::ReadScan(dir + "MLS_Clip.pcd");
  const PointCloud uas = client::ReadScan(dir + "UAS_Clip.pcd");
  ASSERT_EQ(mls.origin, uas.origin);
  const TrunkDetectionResult a = DetectTrunks(mls, MultiViewOptions());
  const TrunkDetectionResult b = DetectTrunks(uas, MultiViewOptions());
  EXPECT_TRUE(a.ground_known);
  EXPECT_TRUE(b.ground_known);
  auto pairs_within = [&](const Eigen::Vector2d& offset, double radius) {
    std::vector<std::pair<const DetectedTrunk*, const DetectedTrunk*>> pairs;
    for (const DetectedTrunk& s : a.trees) {
      const DetectedTrunk* best = nullptr;
      double best_distance = radius;
      for (const DetectedTrunk& t : b.trees) {
        const double d =
            (s.breast_height_point.head<2>() + offset - t.breast_height_point.head<2>()).norm();
        if (d < best_distance) best_distance = d, best = &t;
      }
      if (best) pairs.emplace_back(&s, best);
    }
    return pairs;
  };
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::vector<double> dx, dy;
  for (const auto& [s, t] : pairs_within(Eigen::Vector2d::Zero(), 1.0)) {
    dx.push_back(t->breast_height_point.x() - s->breast_height_point.x());
    dy.push_back(t->breast_height_point.y() - s->breast_height_point.y());
  }
  ASSERT_GE(dx.size(), 8u);
  const Eigen::Vector2d offset(median(dx), median(dy));
  std::vector<double> position, dbh;
  for (const auto& [s, t] : pairs_within(offset, kClipMatch)) {
    position.push_back(
        (s->breast_height_point.head<2>() + offset - t->breast_height_point.head<2>()).norm());
    dbh.push_back(std::abs(s->tree.dbh - t->tree.dbh));
  }
  std::cout << "MLS " << a.trees.size() << " stems, UAS " << b.trees.size() << " stems, offset "
            << offset.transpose() << " m, " << position.size() << " pairs: median position "
            << median(position) << " m, median |dDBH| " << median(dbh) << " m" << std::endl;
  EXPECT_NEAR(offset.norm(), 0.59, 0.1);
  ASSERT_GE(position.size(), 10u);
  EXPECT_LE(median(position), kClipPosition);
  EXPECT_LE(median(dbh), kClipDbh);
}

}  // namespace
}  // namespace forestmap::algorithms
