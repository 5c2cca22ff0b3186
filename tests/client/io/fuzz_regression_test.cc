// Inputs that crashed a reader under libFuzzer (tests/fuzz), minimized: each must now be a
// ScanError naming the file and the problem. Run in the normal build, so the fixes cannot rot.

#include <gtest/gtest.h>

#include <string>

#include "client/io/scan_io.h"
#include "tests/client/io/scan_io_test_util.h"

namespace forestmap::client {
namespace {

using testing_util::ErrorOf;

class FuzzRegressionTest : public testing_util::ScanDirTest {
 protected:
  void ExpectError(const std::string& name, const std::string& content,
                   const std::string& expected) {
    SCOPED_TRACE(name + ": " + expected);
    const std::string path = Write(name, content);
    for (const bool keep_invalid : {false, true}) {
      ScanReadOptions options;
      options.keep_invalid_points = keep_invalid;
      const std::string message = ErrorOf([&] { ReadScan(path, options); });
      EXPECT_NE(message.find(path), std::string::npos) << message;
      EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
  }
};

// fuzz_pcd: PCL drops a field with COUNT 0, so x was missing from its cloud and the reader
// dereferenced null (UBSan: member access within null pointer).
TEST_F(FuzzRegressionTest, PcdFieldWithCountZero) {
  ExpectError("count0.pcd",
              "FIELDS x y z ring\nSIZE 4 4 4 2\nTYPE F F F U\nCOUNT 0 1 1 1\nWIDTH 2\nHEIGHT 1\n"
              "POINTS 2\nDATA binary\n" +
                  std::string(2 * 14, '\0'),
              "field 'x': COUNT must be at least 1");
}

// fuzz_pcd: a header line of only white space (" ", "\t", or "\r" of a CRLF blank line) makes
// PCL 1.13's PCDReader::read dereference null (SEGV inside libpcl_io), even in a valid file.
TEST_F(FuzzRegressionTest, PcdWhiteSpaceHeaderLine) {
  const std::string body =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n";
  for (const std::string blank : {" ", "\t", "\r", "  \r"}) {
    ExpectError("blank.pcd", blank + "\n" + body, ":1: header line of only white space");
  }
  ExpectError("inner.pcd", "FIELDS x y z\nSIZE 4 4 4\n \nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n",
              ":3: header line of only white space");
  // An empty line stays allowed (PCL skips it), and so is a CRLF file without blank lines.
  EXPECT_EQ(ReadScan(Write("empty_line.pcd", "\n" + body)).size(), 1u);
  EXPECT_EQ(ReadScan(Write("crlf.pcd",
                           "FIELDS x y z\r\nSIZE 4 4 4\r\nTYPE F F F\r\nWIDTH 1\r\nPOINTS 1\r\n"
                           "DATA ascii\r\n1 2 3\r\n"))
                .size(),
            1u);
}

// fuzz_pcd (out of memory): PCL reads header lines on after DATA while they look like header, so
// binary data starting "DATA binary_compressed" made PCL take size words from the points and
// allocate 942 MB for a 600-byte file. Data that PCL would read as header is refused.
TEST_F(FuzzRegressionTest, PcdDataThatLooksLikeHeader) {
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 2\nDATA binary\n";
  ExpectError(
      "second_data.pcd",
      head + "\n# c\nDATA binary_compressed\n\x19\x00\x00\x00\x18 38" + std::string(24, '\0'),
      ":9: data after the DATA line starts with header keyword 'DATA'");
  ExpectError("fields.pcd", head + "FIELDSxyz" + std::string(24, '\0'),
              ":7: data after the DATA line starts with header keyword 'FIELDS'");
  // Binary data that merely starts with a newline, a '#' or white space still reads.
  for (const std::string start : {"\n", "#", " \n", "\r\n"}) {
    const std::string data = start + std::string(24 - start.size(), '\0');
    EXPECT_EQ(ReadScan(Write("ok.pcd", head + data), {.keep_invalid_points = true}).size(), 2u);
  }
}

// fuzz_ply: two `element vertex`: the columns were taken from the last, the data read with the
// first, so intensity and ring were written into arrays never sized (UBSan: null reference).
TEST_F(FuzzRegressionTest, PlyTwoVertexElements) {
  ExpectError("two_vertex.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nproperty uchar intensity\nelement vertex 1\nproperty float x\n"
              "property float y\nproperty float z\nend_header\n1 2 3 4\n1 2 3\n",
              "more than one 'element vertex'");
}

// fuzz_pcd (out of memory, found by the 30 s run of deploy/test.sh): no points (HEIGHT 0, the
// POINTS line lost in a garbled VIEWPOINT line), but binary_compressed size words asking for
// 2.4 GB, which PCL allocated. The size words are checked when there are no points too.
TEST_F(FuzzRegressionTest, PcdCompressedSizeWordsWithoutPoints) {
  std::string words(8, '\0');
  words[0] = '\x19';
  words[4] = '\x18';
  words[7] = '\x91';
  ExpectError("no_points.pcd",
              "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 0\n"
              "DATA binary_compressed\n" +
                  words + std::string(25, '\x40'),
              "uncompressed 2432696344) do not fit 0 bytes of points");
}

// fuzz_pcd (out of memory, found by CI's 30 s run): an ascii file of 3 points whose header said
// COUNT 999999991 for one field; PCL allocated points x point step (12 GB) before reading a line.
// A count is bounded, and a header must not promise more values than the file has bytes.
TEST_F(FuzzRegressionTest, PcdHugeCountInAsciiHeader) {
  const std::string head = "FIELDS x y z intensity\nSIZE 8 4 4 4\nTYPE F F F F\n";
  const std::string tail = "WIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n1 2 3 4\n5 6 7 8\n";
  ExpectError("huge_count.pcd", head + "COUNT 1 1 999999991 1\n" + tail,
              "COUNT 999999991 is over 65536 values per field");
  ExpectError("many_values.pcd", head + "COUNT 1 1 60000 1\n" + tail,
              "3 points of 60003 values cannot fit in the 16 bytes of ascii data");
  ExpectError("big_size.pcd", "FIELDS x y z\nSIZE 4 4 4294967300\nTYPE F F F\n" + tail,
              "SIZE must be 1, 2, 4 or 8 bytes, got 4294967300");
}

// fuzz_ply (timeout, found by the 30 s run of deploy/test.sh): an element without properties and
// a count of 10^12 before the vertices; the binary reader counted through it one by one. Such an
// element holds no bytes: the vertices after it read at once.
TEST_F(FuzzRegressionTest, PlyHugeElementWithoutProperties) {
  std::string data(12, '\0');
  data[3] = '\x3f';  // x = 0.5 (little-endian float 0x3f000000)
  const std::string path =
      Write("empty_element.ply",
            "ply\nformat binary_little_endian 1.0\nelement junk 1888888888888\n"
            "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
            "end_header\n" +
                data);
  const auto scan = ReadScan(path);
  ASSERT_EQ(scan.size(), 1u);
}

// fuzz_ply (UBSan, found while checking the two fixes above): an ASCII list length of 5.6e29
// was converted to size_t (undefined). A length beyond the line is now "expected more values".
TEST_F(FuzzRegressionTest, PlyHugeListLength) {
  ExpectError("huge_list.ply",
              "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
              "property float z\nproperty list uchar int vertex_indices\nproperty uchar i\n"
              "end_header\n1 2 3 555555555555555555555555555551 4\n",
              "expected more values");
}

}  // namespace
}  // namespace forestmap::client
