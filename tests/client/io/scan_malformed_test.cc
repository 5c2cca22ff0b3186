// Malformed scans never crash: each gives a ScanError naming the file and the place (line, byte
// or header field). Also every truncation and a fixed-seed set of byte flips of each format.

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "client/io/scan_io.h"
#include "tests/client/io/scan_io_test_util.h"

namespace forestmap::client {
namespace {

using testing_util::ErrorOf;

class ScanMalformedTest : public testing_util::ScanDirTest {
 protected:
  // Expects ReadScan of `content` written as `name` to fail with a message containing the path
  // and `expected`.
  void ExpectError(const std::string& name, const std::string& content,
                   const std::string& expected) {
    SCOPED_TRACE(name + ": " + expected);
    const std::string path = Write(name, content);
    const std::string message = ErrorOf([&] { ReadScan(path); });
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << message;
  }
};

const std::string kPcdHead =
    "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
    "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n";

TEST_F(ScanMalformedTest, EmptyFilesAndUnknownExtensions) {
  for (const char* name : {"e.pcd", "e.ply", "e.las", "e.csv", "e.xyz", "e.txt"}) {
    ExpectError(name, "", "empty file");
  }
  ExpectError("comments.csv", "# nothing\n\n", "no points");
  ExpectError("scan.e57", "data", "unknown scan file extension '.e57'");
  ExpectError("noextension", "data", "unknown scan file extension ''");
  EXPECT_NE(ErrorOf([&] { ReadScan(Path("missing.pcd")); }).find("cannot open"), std::string::npos);
}

TEST_F(ScanMalformedTest, PcdHeaderAndData) {
  ExpectError("a.pcd", "VERSION 0.7\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nDATA ascii\n1 2 3\n",
              "no FIELDS line");
  ExpectError("b.pcd", "FIELDS x y intensity\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
              "no 'z' field");
  ExpectError("c.pcd", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
              "SIZE does not have one entry per field");
  ExpectError("d.pcd", "FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
              "field 'z': TYPE F cannot have SIZE 3");
  ExpectError("e.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nWIDTH 1\nDATA ascii\n1 2 3\n",
              ":3: TYPE must be I, U or F");
  ExpectError("f.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH two\n", ":4: WIDTH must be");
  ExpectError("g.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nDATA ascii\n1 2 3\n",
              "no WIDTH line");
  ExpectError("h.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n", "no DATA line");
  ExpectError("i.pcd", kPcdHead + "DATA zipped\n", "DATA must be ascii, binary or");
  ExpectError("j.pcd",
              "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 2\nPOINTS 5\n"
              "DATA ascii\n",
              "point count mismatch: POINTS 5 but WIDTH x HEIGHT = 4");
  ExpectError("k.pcd", kPcdHead + "DATA binary\n" + std::string(20, '\0'),
              "truncated binary data: 2 points need 24 bytes, the file has 20");
  ExpectError("l.pcd", kPcdHead + "DATA ascii\n1 2 3\n", "could not read the ascii point data");
  ExpectError("m.pcd", kPcdHead + "DATA binary_compressed\n" + std::string(6, '\0'),
              "truncated binary_compressed data");
  ExpectError("n.pcd",
              kPcdHead + "DATA binary_compressed\n" + std::string("\x10\0\0\0\x18\0\0\0", 8),
              "binary_compressed sizes");
  ExpectError("o.pcd", "# offset subtracted: 1 2\n" + kPcdHead + "DATA ascii\n1 2 3\n4 5 6\n",
              ":1: header comment 'offset subtracted:' needs three finite numbers");
  ExpectError("p.pcd", "GARBAGE 1\n", ":1: unknown header keyword 'GARBAGE'");
}

TEST_F(ScanMalformedTest, PlyHeaderAndData) {
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  ExpectError("a.ply", "plx\n", ":1: not a PLY file");
  ExpectError("b.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n",
              ":2: unknown format 'binary_middle_endian'");
  ExpectError("c.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n",
              "no 'element vertex'");
  ExpectError("d.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n",
              "lacks x, y or z");
  ExpectError("e.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
              "no 'end_header'");
  ExpectError("f.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n",
              ":4: unknown property type 'quad'");
  ExpectError("g.ply", head + "1 2 3\n", ":9: unexpected end of file in element 'vertex' 1 of 2");
  ExpectError("h.ply", head + "1 2 3\n4 five 6\n", ":9: column 2: not a number");
  ExpectError("i.ply", head + "1 2 3\n4 5\n", ":9: expected more values");
  ExpectError("j.ply",
              "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
              "property float y\nproperty float z\nend_header\n" +
                  std::string(20, '\0'),
              "truncated binary data in element 'vertex' 1 of 2");
  ExpectError("k.ply",
              "ply\nformat binary_little_endian 1.0\nelement vertex 99999999\n"
              "property float x\nproperty float y\nproperty float z\nend_header\n",
              "point count mismatch: header says 99999999 vertices");
}

TEST_F(ScanMalformedTest, TextLinesNameFileAndLine) {
  ExpectError("a.csv", "x,y,z\n1,2,3\n4,abc,6\n", ":3: column 2: 'abc' is not a number");
  ExpectError("b.csv", "x,y,z\n1,2,3\n4,5\n", ":3: expected 3 values, found 2");
  ExpectError("c.xyz", "1 2\n", ":1: expected at least 3 values");
  ExpectError("d.csv", "a,b,c\n1,2,3\n", ":1: header line has no x, y and z columns");
  ExpectError("e.txt", "1 2 3\n4 5 6 7\n", ":2: expected 3 values, found 4");
  ExpectError("f.csv", "x,y,z\n1,,3\n", ":2: column 2: '' is not a number");
  ExpectError("g.csv", "# organised: 2 2\nx,y,z\n1,2,3\n",
              "point count mismatch: 'organised: 2 2'");
}

TEST_F(ScanMalformedTest, PlanarCsv) {
  auto expect = [&](const std::string& text, const std::string& expected) {
    SCOPED_TRACE(expected);
    const std::string path = Write("p.csv", text);
    const std::string message = ErrorOf([&] { ReadPlanarScan(path); });
    EXPECT_NE(message.find(path + expected), std::string::npos) << message;
  };
  expect("angle_rad,range_m\n0,1\nnan,1\n", ":3: angle_rad is not finite");
  expect("angle_rad,range_m\n0,-1\n", ":2: range_m is negative");
  expect("angle_rad,range_m\n0,one\n", ":2: column 2: 'one' is not a number");
  expect("bearing,distance\n0,1\n", ":1: header line has no angle_rad and range_m");
  expect("", ": empty file");
}

// Every prefix of a valid file, and random byte flips, give a ScanError or a cloud; never a
// crash or another exception (run under the sanitizers in CI).
TEST_F(ScanMalformedTest, TruncationsAndByteFlipsNeverCrash) {
  algorithms::PointCloud cloud;
  cloud.width = 8;
  cloud.height = 3;
  for (int i = 0; i < 24; ++i) {
    cloud.points.emplace_back(i * 0.5f, -i * 0.25f, 1.0f + i);
    cloud.intensity.push_back(static_cast<float>(i));
    cloud.ring.push_back(static_cast<uint16_t>(i / 8));
  }
  cloud.origin = Eigen::Vector3d(1000, 2000, 300);
  std::mt19937 rng(42);
  struct Variant {
    const char* name;
    PcdEncoding encoding;
  };
  for (const Variant& v :
       {Variant{"s.pcd", PcdEncoding::kBinary}, Variant{"t.pcd", PcdEncoding::kAscii},
        Variant{"u.pcd", PcdEncoding::kBinaryCompressed}, Variant{"s.ply", PcdEncoding::kBinary},
        Variant{"s.csv", PcdEncoding::kBinary}}) {
    SCOPED_TRACE(v.name);
    ScanWriteOptions options;
    options.pcd_encoding = v.encoding;
    WriteScan(Path(v.name), cloud, options);
    std::ifstream in(Path(v.name), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(bytes.empty());
    for (size_t length = 0; length < bytes.size(); length += 5) {
      const std::string path = Write(v.name, bytes.substr(0, length));
      try {
        ReadScan(path);
      } catch (const ScanError&) {
      }
    }
    for (int trial = 0; trial < 100; ++trial) {
      std::string flipped = bytes;
      flipped[rng() % flipped.size()] = static_cast<char>(rng());
      const std::string path = Write(v.name, flipped);
      try {
        ReadScan(path);
      } catch (const ScanError&) {
      }
    }
  }
}

}  // namespace
}  // namespace forestmap::client
