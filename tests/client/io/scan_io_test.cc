// Scan I/O: the real scans of the shared data, and round trips through every written format.

#include "client/io/scan_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <string>

#include "tests/client/io/scan_io_test_util.h"
#include "tests/shared_data.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;
using algorithms::PointCloud;
using testing_util::Absolute;
using testing_util::ErrorOf;
using testing_util::ScanDirTest;

const std::string kScans = std::string(FORESTMAP_SHARED_DATA) + "/scans";
constexpr double kMillimetre = 1e-3;  // m

#define SKIP_WITHOUT(path) \
  if (!fs::exists(path)) FORESTMAP_SKIP_WITHOUT_DATA() << "shared data missing: " << (path)

size_t CountFinite(const PointCloud& cloud) {
  size_t n = 0;
  for (const auto& p : cloud.points) n += p.allFinite() ? 1 : 0;
  return n;
}

TEST(ScanIoRealData, TreescopeTrunkSlicesHaveReferencePointCounts) {
  const std::string dir = kScans + "/treescope_trunk_slices";
  SKIP_WITHOUT(dir + "/reference.csv");
  std::ifstream reference(dir + "/reference.csv");
  std::string line;
  std::getline(reference, line);  // header: file,tree_id,n_points,...
  int files = 0;
  while (std::getline(reference, line)) {
    std::stringstream row(line);
    std::string file, tree_id, n_points;
    std::getline(row, file, ',');
    std::getline(row, tree_id, ',');
    std::getline(row, n_points, ',');
    const PointCloud cloud = ReadScan(dir + "/" + file);
    EXPECT_EQ(cloud.size(), std::stoul(n_points)) << file;
    EXPECT_EQ(cloud.width, cloud.size()) << file;
    EXPECT_EQ(cloud.height, 1u) << file;
    EXPECT_EQ(CountFinite(cloud), cloud.size()) << file;
    EXPECT_TRUE(cloud.origin.isZero()) << file;  // plot frame, tens of metres
    ++files;
  }
  EXPECT_EQ(files, 13);
}

// The PCD was converted from the same points with "offset subtracted: 101 151 4" in its header
// comment; the LAS holds them as integers of 1 mm plus Range/Ring/hag/cluster extra bytes.
TEST(ScanIoRealData, LidrSlicePcdAndLasAgree) {
  const std::string dir = kScans + "/lidr_dbh_slice";
  SKIP_WITHOUT(dir + "/dbh.las");
  const PointCloud pcd = ReadScan(dir + "/dbh.pcd");
  const PointCloud las = ReadScan(dir + "/dbh.las");
  ASSERT_EQ(pcd.size(), 1369u);
  ASSERT_EQ(las.size(), 1369u);
  EXPECT_EQ(pcd.origin, Eigen::Vector3d(101, 151, 4));
  EXPECT_TRUE(las.origin.isZero());  // small coordinates: no shift needed
  for (size_t i = 0; i < las.size(); ++i) {
    ASSERT_LT((Absolute(pcd, i) - Absolute(las, i)).norm(), kMillimetre) << "point " << i;
  }
  ASSERT_EQ(las.ring.size(), las.size());
  std::set<uint16_t> rings(las.ring.begin(), las.ring.end());
  EXPECT_GE(rings.size(), 2u);
  EXPECT_LE(*rings.rbegin(), 15);  // a 16-beam scanner
  ASSERT_EQ(pcd.intensity.size(), pcd.size());
  ASSERT_EQ(las.intensity.size(), las.size());
  for (size_t i = 0; i < las.size(); ++i) ASSERT_EQ(pcd.intensity[i], las.intensity[i]);
}

// LAS 1.4 format 7 with scale 0.1 mm in UTM; the PCD has the offset in its header comment.
TEST(ScanIoRealData, SpannerMobileLasAndPcdAgree) {
  const std::string dir = kScans + "/spanner_ponderosa";
  SKIP_WITHOUT(dir + "/MLS_Clip.las");
  const PointCloud pcd = ReadScan(dir + "/MLS_Clip.pcd");
  const PointCloud las = ReadScan(dir + "/MLS_Clip.las");
  ASSERT_EQ(pcd.size(), 301477u);
  ASSERT_EQ(las.size(), 301477u);
  const Eigen::Vector3d utm_floor(470627, 3810222, 2278);  // floor of the header's min bound
  EXPECT_EQ(pcd.origin, utm_floor);
  EXPECT_EQ(las.origin, utm_floor);
  double worst = 0;
  float lowest = std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < las.size(); ++i) {
    worst = std::max(worst, (pcd.points[i] - las.points[i]).cast<double>().cwiseAbs().maxCoeff());
    lowest = std::min(lowest, las.points[i].minCoeff());
  }
  // The LAS keeps 0.1 mm; the PCD's converter rounded to 1 mm (per axis at most 0.5 mm off);
  // float relative to the origin (< 40 m) adds at most ~4 um.
  EXPECT_LT(worst, 0.5 * kMillimetre + 1e-5);
  EXPECT_GE(lowest, 0.0f);  // the origin is the floor of the min bound
}

TEST(ScanIoRealData, SpannerDroneAndAirbornePcdShareTheUtmOrigin) {
  const std::string dir = kScans + "/spanner_ponderosa";
  SKIP_WITHOUT(dir + "/UAS_Clip.pcd");
  EXPECT_EQ(ReadScan(dir + "/UAS_Clip.pcd").size(), 390877u);
  const PointCloud als = ReadScan(dir + "/ALS_Clip.pcd");
  EXPECT_EQ(als.size(), 29915u);
  EXPECT_EQ(als.origin, Eigen::Vector3d(470627, 3810222, 2278));
}

TEST(ScanIoRealData, SloamOusterTreeFramesAreOrganisedWithNaNs) {
  const std::string dir = kScans + "/sloam_uav_ouster";
  SKIP_WITHOUT(dir + "/still_tree_t0.pcd");
  for (const char* name : {"still_tree_t0", "still_tree_t1", "moving_tree_t0", "moving_tree_t1"}) {
    const PointCloud cloud = ReadScan(dir + "/" + name + ".pcd");
    EXPECT_EQ(cloud.width, 2048u) << name;
    EXPECT_EQ(cloud.height, 64u) << name;
    ASSERT_EQ(cloud.size(), 2048u * 64u) << name;
    ASSERT_EQ(cloud.intensity.size(), cloud.size()) << name;
    const size_t finite = CountFinite(cloud);
    EXPECT_GE(finite, 4500u) << name;  // ORIGIN.md: 4.5k-6.6k tree points per frame
    EXPECT_LE(finite, 6600u) << name;
  }
  // The ground files are unorganised lists of valid points.
  const PointCloud ground = ReadScan(dir + "/still_ground_t0.pcd");
  EXPECT_EQ(ground.size(), 54393u);
  EXPECT_EQ(ground.height, 1u);
  EXPECT_EQ(CountFinite(ground), ground.size());
}

// ---- Round trips through every written format ----

PointCloud OrganisedUtmCloud() {
  PointCloud cloud;
  cloud.width = 16;
  cloud.height = 4;
  cloud.origin = Eigen::Vector3d(470627.0, 3810222.0, 2278.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (uint32_t row = 0; row < cloud.height; ++row) {
    for (uint32_t col = 0; col < cloud.width; ++col) {
      const bool no_return = (row * 7 + col) % 5 == 0;
      cloud.points.push_back(no_return ? Eigen::Vector3f(nan, nan, nan)
                                       : Eigen::Vector3f(0.123456f * col, -3.5f + row * 1e-4f,
                                                         27.000123f - col * 0.01f));
      cloud.intensity.push_back(no_return ? 0.0f : 10.5f + col);
      cloud.ring.push_back(static_cast<uint16_t>(row));
    }
  }
  return cloud;
}

void ExpectSameCloud(const PointCloud& expected, const PointCloud& actual) {
  ASSERT_EQ(actual.size(), expected.size());
  EXPECT_EQ(actual.width, expected.width);
  EXPECT_EQ(actual.height, expected.height);
  EXPECT_EQ(actual.origin, expected.origin);
  ASSERT_EQ(actual.intensity.size(), expected.intensity.size());
  ASSERT_EQ(actual.ring.size(), expected.ring.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    if (!expected.points[i].allFinite()) {
      EXPECT_TRUE(actual.points[i].array().isNaN().all()) << "point " << i;
    } else {
      EXPECT_EQ(actual.points[i], expected.points[i]) << "point " << i;  // bit-exact
    }
  }
  EXPECT_EQ(actual.intensity, expected.intensity);
  EXPECT_EQ(actual.ring, expected.ring);
}

class ScanRoundTripTest : public ScanDirTest {};

TEST_F(ScanRoundTripTest, OrganisedCloudSurvivesEveryFormat) {
  const PointCloud cloud = OrganisedUtmCloud();
  struct Case {
    const char* name;
    PcdEncoding encoding;
  };
  for (const Case& c :
       {Case{"a.pcd", PcdEncoding::kBinary}, Case{"b.pcd", PcdEncoding::kAscii},
        Case{"c.pcd", PcdEncoding::kBinaryCompressed}, Case{"d.ply", PcdEncoding::kBinary},
        Case{"e.csv", PcdEncoding::kBinary}, Case{"F.PCD", PcdEncoding::kBinary}}) {
    SCOPED_TRACE(c.name);
    ScanWriteOptions options;
    options.pcd_encoding = c.encoding;
    WriteScan(Path(c.name), cloud, options);
    ExpectSameCloud(cloud, ReadScan(Path(c.name)));
  }
}

// A real organised Ouster frame (ascii PCD with NaNs) through each written format.
TEST_F(ScanRoundTripTest, RealOrganisedOusterFrame) {
  const std::string frame = kScans + "/sloam_uav_ouster/moving_tree_t1.pcd";
  SKIP_WITHOUT(frame);
  const PointCloud cloud = ReadScan(frame);
  ASSERT_TRUE(cloud.IsOrganised());
  for (const char* name : {"frame.pcd", "frame.ply", "frame.csv"}) {
    SCOPED_TRACE(name);
    WriteScan(Path(name), cloud);
    ExpectSameCloud(cloud, ReadScan(Path(name)));
  }
}

TEST_F(ScanRoundTripTest, UnorganisedWithoutOptionalFields) {
  PointCloud cloud;
  for (int i = 0; i < 1000; ++i) {
    cloud.points.emplace_back(std::sin(i) * 20.0f, std::cos(i) * 20.0f, i * 0.001f);
  }
  cloud.width = static_cast<uint32_t>(cloud.size());
  for (const char* name : {"u.pcd", "u.ply", "u.csv"}) {
    SCOPED_TRACE(name);
    WriteScan(Path(name), cloud);
    ExpectSameCloud(cloud, ReadScan(Path(name)));
  }
}

TEST_F(ScanRoundTripTest, UnorganisedNaNsAreDroppedUnlessKept) {
  PointCloud cloud;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.points = {{1, 2, 3}, {nan, nan, nan}, {4, 5, 6}};
  cloud.intensity = {1, 2, 3};
  cloud.width = 3;
  for (const char* name : {"n.pcd", "n.ply", "n.csv"}) {
    SCOPED_TRACE(name);
    WriteScan(Path(name), cloud);
    const PointCloud dropped = ReadScan(Path(name));
    ASSERT_EQ(dropped.size(), 2u);
    EXPECT_EQ(dropped.width, 2u);
    EXPECT_EQ(dropped.points[1], Eigen::Vector3f(4, 5, 6));
    EXPECT_EQ(dropped.intensity, (std::vector<float>{1, 3}));
    ScanReadOptions keep;
    keep.keep_invalid_points = true;
    ExpectSameCloud(cloud, ReadScan(Path(name), keep));
  }
}

TEST_F(ScanRoundTripTest, PlanarScanWithNoReturns) {
  algorithms::PlanarScan scan;
  for (int i = 0; i < 360; ++i) {
    scan.angles.push_back(static_cast<float>(-M_PI + i * M_PI / 180.0));
    scan.ranges.push_back(i % 10 == 0   ? std::numeric_limits<float>::quiet_NaN()
                          : i % 10 == 1 ? std::numeric_limits<float>::infinity()
                                        : 1.0f + i * 0.0123f);
  }
  WritePlanarScan(Path("p.csv"), scan);
  const algorithms::PlanarScan back = ReadPlanarScan(Path("p.csv"));
  ASSERT_EQ(back.size(), scan.size());
  EXPECT_EQ(back.angles, scan.angles);
  for (size_t i = 0; i < scan.size(); ++i) {
    if (std::isnan(scan.ranges[i])) {
      EXPECT_TRUE(std::isnan(back.ranges[i]));
    } else {
      EXPECT_EQ(back.ranges[i], scan.ranges[i]);
    }
  }
}

TEST_F(ScanRoundTripTest, WriteRejectsInconsistentCloudsAndUnknownExtensions) {
  PointCloud cloud;
  cloud.points = {{1, 2, 3}};
  cloud.width = 2;  // does not match
  EXPECT_NE(ErrorOf([&] { WriteScan(Path("x.pcd"), cloud); }).find("width x height"),
            std::string::npos);
  cloud.width = 1;
  cloud.intensity = {1, 2};
  EXPECT_NE(ErrorOf([&] { WriteScan(Path("x.ply"), cloud); }).find("intensity"), std::string::npos);
  cloud.intensity.clear();
  EXPECT_NE(ErrorOf([&] { WriteScan(Path("x.las"), cloud); }).find("cannot write scans as '.las'"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { WriteScan(Path("no_such_dir/x.pcd"), cloud); }).find("no_such_dir/x.pcd"),
            std::string::npos);
  algorithms::PlanarScan scan;
  scan.angles = {0.0f};
  EXPECT_NE(ErrorOf([&] { WritePlanarScan(Path("p.csv"), scan); }).find("1 angles but 0 ranges"),
            std::string::npos);
}

}  // namespace
}  // namespace forestmap::client
