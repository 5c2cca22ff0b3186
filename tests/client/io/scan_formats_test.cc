// Reading hand-written files of each text and binary variant that WriteScan does not produce:
// PLY ascii / big endian / double / with faces, PCD with double fields of UTM size, CSV/XYZ/TXT
// dialects, planar CSV with and without header.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "client/io/scan_io.h"
#include "tests/client/io/scan_io_test_util.h"

namespace forestmap::client {
namespace {

using algorithms::PointCloud;
using testing_util::Absolute;

class ScanFormatsTest : public testing_util::ScanDirTest {};

template <typename T>
std::string Bytes(T value, bool big_endian = false) {
  std::string out(sizeof(T), '\0');
  std::memcpy(out.data(), &value, sizeof(T));
  if (big_endian) std::reverse(out.begin(), out.end());
  return out;
}

// UTM-sized doubles must keep sub-millimetre precision (float alone would keep ~0.25 m).
const Eigen::Vector3d kUtmA(470630.1234, 3810230.5678, 2290.4321);
const Eigen::Vector3d kUtmB(470640.0001, 3810225.9999, 2280.0005);

TEST_F(ScanFormatsTest, PlyAsciiWithElementsAroundTheVertices) {
  const std::string path = Write("a.ply",
                                 "ply\nformat ascii 1.0\ncomment made by hand\n"
                                 "element camera 1\nproperty float fx\nproperty float fy\n"
                                 "element vertex 3\nproperty double x\nproperty double y\n"
                                 "property double z\nproperty uchar red\nproperty float intensity\n"
                                 "property ushort ring\n"
                                 "element face 1\nproperty list uchar int vertex_indices\n"
                                 "end_header\n"
                                 "500 500\n"
                                 "470630.1234 3810230.5678 2290.4321 255 12.5 3\n"
                                 "470640.0001 3810225.9999 2280.0005 0 7 1\r\n"
                                 "nan nan nan 0 0 2\n"
                                 "3 0 1 2\n");
  const PointCloud cloud = ReadScan(path);
  ASSERT_EQ(cloud.size(), 2u);  // the NaN vertex of an unorganised cloud is dropped
  EXPECT_EQ(cloud.origin, Eigen::Vector3d(470630, 3810225, 2280));
  EXPECT_LT((Absolute(cloud, 0) - kUtmA).norm(), 1e-5);
  EXPECT_LT((Absolute(cloud, 1) - kUtmB).norm(), 1e-5);
  EXPECT_EQ(cloud.intensity, (std::vector<float>{12.5f, 7.0f}));
  EXPECT_EQ(cloud.ring, (std::vector<uint16_t>{3, 1}));
}

std::string BinaryPly(bool big_endian) {
  std::string out = std::string("ply\nformat ") +
                    (big_endian ? "binary_big_endian" : "binary_little_endian") +
                    " 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "element vertex 2\nproperty double x\nproperty double y\nproperty double z\n"
                    "property short scalar_Intensity\nend_header\n";
  out += Bytes<uint8_t>(2) + Bytes<int32_t>(0, big_endian) + Bytes<int32_t>(1, big_endian);
  for (const Eigen::Vector3d& p : {kUtmA, kUtmB}) {
    for (int a = 0; a < 3; ++a) out += Bytes<double>(p[a], big_endian);
    out += Bytes<int16_t>(-4, big_endian);
  }
  return out;
}

TEST_F(ScanFormatsTest, PlyBinaryBothEndiansWithFacesFirst) {
  for (bool big_endian : {false, true}) {
    SCOPED_TRACE(big_endian ? "big endian" : "little endian");
    const PointCloud cloud = ReadScan(Write("b.ply", BinaryPly(big_endian)));
    ASSERT_EQ(cloud.size(), 2u);
    EXPECT_LT((Absolute(cloud, 0) - kUtmA).norm(), 1e-5);
    EXPECT_LT((Absolute(cloud, 1) - kUtmB).norm(), 1e-5);
    EXPECT_EQ(cloud.intensity, (std::vector<float>{-4.0f, -4.0f}));
    EXPECT_TRUE(cloud.ring.empty());
  }
}

TEST_F(ScanFormatsTest, PcdDoubleFieldsKeepUtmPrecision) {
  std::string pcd =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity ring\nSIZE 8 8 8 1 2\nTYPE F F F U U\n"
      "COUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n";
  for (const Eigen::Vector3d& p : {kUtmA, kUtmB}) {
    for (int a = 0; a < 3; ++a) pcd += Bytes<double>(p[a]);
    pcd += Bytes<uint8_t>(200) + Bytes<uint16_t>(63);
  }
  const PointCloud cloud = ReadScan(Write("d.pcd", pcd));
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.origin, Eigen::Vector3d(470630, 3810225, 2280));
  EXPECT_LT((Absolute(cloud, 0) - kUtmA).norm(), 1e-5);
  EXPECT_LT((Absolute(cloud, 1) - kUtmB).norm(), 1e-5);
  EXPECT_EQ(cloud.intensity, (std::vector<float>{200, 200}));
  EXPECT_EQ(cloud.ring, (std::vector<uint16_t>{63, 63}));
}

TEST_F(ScanFormatsTest, PcdOffsetCommentAndOrganisedAscii) {
  const std::string path = Write("o.pcd",
                                 "# converted; offset subtracted: 100.5 -200 3\nVERSION 0.7\n"
                                 "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\n"
                                 "HEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n"
                                 "1 2 3\nnan nan nan\n4 5 6\ninf 0 0\n");
  const PointCloud cloud = ReadScan(path);
  EXPECT_EQ(cloud.origin, Eigen::Vector3d(100.5, -200, 3));
  ASSERT_EQ(cloud.size(), 4u);
  EXPECT_EQ(cloud.width, 2u);
  EXPECT_EQ(cloud.height, 2u);
  EXPECT_EQ(cloud.points[2], Eigen::Vector3f(4, 5, 6));
  EXPECT_TRUE(cloud.points[1].array().isNaN().all());
  EXPECT_TRUE(cloud.points[3].array().isNaN().all());  // inf becomes "no return" too
}

TEST_F(ScanFormatsTest, TextDialects) {
  struct Case {
    const char* name;
    const char* text;
    bool has_intensity;
  };
  const Case cases[] = {
      {"spaces.xyz", "1 2 3\n4   5\t6\n", false},
      {"tabs.txt", "# a comment\n1\t2\t3\t9\n\n4\t5\t6\t10\n", true},
      {"header.csv", "\xEF\xBB\xBFX, Y, Z, Intensity\r\n1, 2, 3, 9\r\n4,5,6,10\r\n", true},
      {"reordered.csv", "intensity,z,y,x\n9,3,2,1\n10,6,5,4\n", true},
      {"cloudcompare.txt", "//X Y Z\n1 2 3\n+4 5 6e0\n", false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const PointCloud cloud = ReadScan(Write(c.name, c.text));
    ASSERT_EQ(cloud.size(), 2u);
    EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1, 2, 3));
    EXPECT_EQ(cloud.points[1], Eigen::Vector3f(4, 5, 6));
    if (c.has_intensity) {
      EXPECT_EQ(cloud.intensity, (std::vector<float>{9, 10}));
    } else {
      EXPECT_TRUE(cloud.intensity.empty());
    }
  }
}

TEST_F(ScanFormatsTest, TextWithUtmCoordinatesKeepsPrecision) {
  const PointCloud cloud = ReadScan(Write("utm.csv",
                                          "x,y,z\n470630.1234,3810230.5678,2290.4321\n"
                                          "470640.0001,3810225.9999,2280.0005\n"));
  EXPECT_EQ(cloud.origin, Eigen::Vector3d(470630, 3810225, 2280));
  EXPECT_LT((Absolute(cloud, 0) - kUtmA).norm(), 1e-5);
  EXPECT_LT((Absolute(cloud, 1) - kUtmB).norm(), 1e-5);
}

TEST_F(ScanFormatsTest, PlanarCsvWithAndWithoutHeader) {
  for (const char* text :
       {"angle_rad,range_m\n0.5,2\n-0.5,nan\n1.5,inf\n", "# no header\n0.5 2\n-0.5 nan\n1.5 inf\n",
        "range_m,angle_rad\n2,0.5\nnan,-0.5\ninf,1.5\n"}) {
    SCOPED_TRACE(text);
    const algorithms::PlanarScan scan = ReadPlanarScan(Write("p.csv", text));
    ASSERT_EQ(scan.size(), 3u);
    EXPECT_EQ(scan.angles, (std::vector<float>{0.5f, -0.5f, 1.5f}));
    EXPECT_EQ(scan.ranges[0], 2.0f);
    EXPECT_TRUE(std::isnan(scan.ranges[1]));
    EXPECT_TRUE(std::isinf(scan.ranges[2]));
  }
}

}  // namespace
}  // namespace forestmap::client
