// LAS reading: every point data format 0-10 in versions 1.2-1.4 built byte by byte from the
// ASPRS LAS 1.4 R15 layout, extra-bytes ring attributes, and each kind of malformed file.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "client/io/scan_io.h"
#include "tests/client/io/scan_io_test_util.h"

namespace forestmap::client {
namespace {

using testing_util::ErrorOf;

constexpr uint16_t kFormatSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr double kScale = 0.001;                          // m per integer step
const Eigen::Vector3d kOffset(470000.0, 3810000.0, 0.0);  // m (UTM-sized)

struct LasSpec {
  int minor = 2;
  int format = 0;
  int ring_type = 0;  // 0: no ring attribute; else extra-bytes type (1 uchar, 10 double)
  size_t undocumented_extra = 0;  // bytes after the standard record with no descriptor
  bool legacy_count = true;       // LAS 1.4 formats 6-10 leave the 32-bit count at 0
};

template <typename T>
void Put(std::string* bytes, size_t offset, T value) {
  std::memcpy(bytes->data() + offset, &value, sizeof(T));
}

struct LasPoint {
  Eigen::Vector3d position;  // m, on the 1 mm grid
  uint16_t intensity;
  uint16_t ring;
};

std::vector<LasPoint> TestPoints() {
  std::vector<LasPoint> points;
  for (int i = 0; i < 50; ++i) {
    points.push_back(
        {Eigen::Vector3d(470627.001 + i * 0.137, 3810222.5 + (i % 7) * 1.001, 2278.25 + i * 0.011),
         static_cast<uint16_t>(100 + 37 * i), static_cast<uint16_t>(i % 16)});
  }
  return points;
}

// One extra-bytes descriptor (192 bytes): type, name, and for doubles scale 1 / offset 0 set.
std::string Descriptor(int type, const char* name, int options = 0) {
  std::string d(192, '\0');
  d[2] = static_cast<char>(type);
  d[3] = static_cast<char>(options);
  std::memcpy(d.data() + 4, name, std::strlen(name));
  return d;
}

std::string BuildLas(const LasSpec& spec, const std::vector<LasPoint>& points) {
  const size_t header_size = spec.minor == 4 ? 375 : spec.minor == 3 ? 235 : 227;
  std::string vlrs;
  size_t extra = spec.undocumented_extra;
  size_t ring_offset = 0;
  if (spec.ring_type != 0) {
    // A float "Range" first, so that the ring sits at a non-zero offset in the extra bytes.
    const std::string body = Descriptor(9, "Range") + Descriptor(spec.ring_type, "Ring");
    std::string vlr(54, '\0');
    std::memcpy(vlr.data() + 2, "LASF_Spec", 9);
    Put<uint16_t>(&vlr, 18, 4);
    Put<uint16_t>(&vlr, 20, static_cast<uint16_t>(body.size()));
    vlrs = vlr + body;
    ring_offset = kFormatSize[spec.format] + 4;
    extra += 4 + (spec.ring_type == 10 ? 8 : 1);
  }
  const size_t record = kFormatSize[spec.format] + extra;
  std::string bytes(header_size, '\0');
  std::memcpy(bytes.data(), "LASF", 4);
  bytes[24] = 1;
  bytes[25] = static_cast<char>(spec.minor);
  Put<uint16_t>(&bytes, 94, static_cast<uint16_t>(header_size));
  Put<uint32_t>(&bytes, 96, static_cast<uint32_t>(header_size + vlrs.size()));
  Put<uint32_t>(&bytes, 100, spec.ring_type != 0 ? 1 : 0);
  bytes[104] = static_cast<char>(spec.format);
  Put<uint16_t>(&bytes, 105, static_cast<uint16_t>(record));
  Put<uint32_t>(&bytes, 107, spec.legacy_count ? static_cast<uint32_t>(points.size()) : 0);
  for (int a = 0; a < 3; ++a) {
    Put<double>(&bytes, 131 + 8 * a, kScale);
    Put<double>(&bytes, 155 + 8 * a, kOffset[a]);
  }
  if (spec.minor == 4) Put<uint64_t>(&bytes, 247, points.size());
  bytes += vlrs;
  for (const LasPoint& p : points) {
    std::string r(record, '\0');
    for (int a = 0; a < 3; ++a) {
      Put<int32_t>(&r, 4 * a,
                   static_cast<int32_t>(std::lround((p.position[a] - kOffset[a]) / kScale)));
    }
    Put<uint16_t>(&r, 12, p.intensity);
    if (spec.ring_type == 1) r[ring_offset] = static_cast<char>(p.ring);
    if (spec.ring_type == 10) Put<double>(&r, ring_offset, p.ring);
    bytes += r;
  }
  return bytes;
}

class LasIoTest : public testing_util::ScanDirTest {};

TEST_F(LasIoTest, EveryFormatOfEveryVersion) {
  const std::vector<LasPoint> truth = TestPoints();
  const Eigen::Vector3d floor_min(470627.0, 3810222.0, 2278.0);
  for (int minor = 2; minor <= 4; ++minor) {
    const int max_format = minor == 4 ? 10 : minor == 3 ? 5 : 3;
    for (int format = 0; format <= max_format; ++format) {
      SCOPED_TRACE("LAS 1." + std::to_string(minor) + " format " + std::to_string(format));
      LasSpec spec;
      spec.minor = minor;
      spec.format = format;
      spec.ring_type = minor == 4 ? (format % 2 == 0 ? 1 : 10) : 0;
      spec.undocumented_extra = minor == 3 ? 3 : 0;
      spec.legacy_count = !(minor == 4 && format >= 6);
      const std::string path = Write("scan.las", BuildLas(spec, truth));
      const algorithms::PointCloud cloud = ReadScan(path);
      ASSERT_EQ(cloud.size(), truth.size());
      EXPECT_EQ(cloud.width, truth.size());
      EXPECT_EQ(cloud.origin, floor_min);
      ASSERT_EQ(cloud.intensity.size(), truth.size());
      ASSERT_EQ(cloud.ring.size(), spec.ring_type != 0 ? truth.size() : 0u);
      for (size_t i = 0; i < truth.size(); ++i) {
        const Eigen::Vector3d absolute = cloud.origin + cloud.points[i].cast<double>();
        // Float relative to the origin (< 10 m here) is good to ~1 um.
        ASSERT_LT((absolute - truth[i].position).norm(), 1e-5) << "point " << i;
        EXPECT_EQ(cloud.intensity[i], truth[i].intensity);
        if (spec.ring_type != 0) {
          EXPECT_EQ(cloud.ring[i], truth[i].ring);
        }
      }
    }
  }
}

TEST_F(LasIoTest, LargeCoordinateLimitIsAnOption) {
  std::vector<LasPoint> points = {{Eigen::Vector3d(470001.5, 3810002.25, -1.0), 7, 0}};
  // Relative to the offset these are small, but LAS stores them absolute: 470 km is large.
  const algorithms::PointCloud cloud = ReadScan(Write("a.las", BuildLas({}, points)));
  EXPECT_EQ(cloud.origin, Eigen::Vector3d(470001, 3810002, -1));
  ScanReadOptions huge_limit;
  huge_limit.large_coordinate_m = 1e7;
  EXPECT_TRUE(ReadScan(Path("a.las"), huge_limit).origin.isZero());
}

struct Corruption {
  const char* name;
  void (*apply)(std::string* bytes);
  const char* message;
};

TEST_F(LasIoTest, MalformedFilesGiveErrorsNamingTheProblem) {
  LasSpec spec;
  spec.minor = 4;
  spec.format = 1;
  spec.ring_type = 1;
  const std::string valid = BuildLas(spec, TestPoints());
  const Corruption corruptions[] = {
      {"signature", [](std::string* b) { (*b)[0] = 'X'; }, "byte 0: wrong signature"},
      {"version 2.0",
       [](std::string* b) {
         (*b)[24] = 2;
         (*b)[25] = 0;
       },
       "unsupported LAS version 2.0"},
      {"version 1.5", [](std::string* b) { (*b)[25] = 5; }, "unsupported LAS version 1.5"},
      {"format 11", [](std::string* b) { (*b)[104] = 11; }, "point data format 11 is not defined"},
      {"format 6 in 1.2",
       [](std::string* b) {
         (*b)[25] = 2;
         (*b)[104] = 6;
       },
       "not defined for LAS 1.2"},
      {"compressed bit", [](std::string* b) { (*b)[104] = static_cast<char>(0x81); },
       "LAZ is compressed"},
      {"laszip vlr",
       [](std::string* b) { std::memcpy(b->data() + 375 + 2, "laszip encoded\0\0", 16); },
       "LAZ is compressed: decompress first"},
      {"record length", [](std::string* b) { Put<uint16_t>(b, 105, 10); },
       "byte 105: point record length 10"},
      {"truncated", [](std::string* b) { b->resize(b->size() - 5); }, "truncated point data"},
      {"count mismatch", [](std::string* b) { Put<uint32_t>(b, 107, 49); }, "point count mismatch"},
      {"too many points",
       [](std::string* b) {
         Put<uint64_t>(b, 247, 1ull << 40);
         Put<uint32_t>(b, 107, 0);
       },
       "truncated point data"},
      {"point offset", [](std::string* b) { Put<uint32_t>(b, 96, 1u << 30); },
       "byte 96: offset to point data"},
      {"header size", [](std::string* b) { Put<uint16_t>(b, 94, 100); }, "header size 100 invalid"},
      {"short file", [](std::string* b) { b->resize(100); }, "file too short for a LAS header"},
      {"vlr overflow", [](std::string* b) { Put<uint16_t>(b, 375 + 20, 60000); },
       "runs past the start"},
      {"vlr count", [](std::string* b) { Put<uint32_t>(b, 100, 5); }, "VLR 1 of 5"},
      {"extra bytes", [](std::string* b) { (*b)[375 + 54 + 192 + 2] = 10; },
       "extra bytes attributes need"},
      {"zero scale", [](std::string* b) { Put<double>(b, 131, 0.0); },
       "invalid scale or offset for axis x"},
  };
  for (const Corruption& c : corruptions) {
    SCOPED_TRACE(c.name);
    std::string bytes = valid;
    c.apply(&bytes);
    const std::string path = Write("bad.las", bytes);
    const std::string message = ErrorOf([&] { ReadScan(path); });
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_NE(message.find(c.message), std::string::npos) << message;
  }
}

TEST_F(LasIoTest, EveryTruncationIsAnErrorNeverACrash) {
  LasSpec spec;
  spec.minor = 4;
  spec.format = 7;
  spec.ring_type = 10;
  const std::string valid = BuildLas(spec, TestPoints());
  for (size_t length = 0; length < valid.size(); length += 7) {
    const std::string path = Write("cut.las", valid.substr(0, length));
    EXPECT_FALSE(ErrorOf([&] { ReadScan(path); }).empty()) << "length " << length;
  }
}

TEST_F(LasIoTest, LazAndEmptyFiles) {
  const std::string laz = Write("cloud.LAZ", "anything");
  EXPECT_NE(
      ErrorOf([&] { ReadScan(laz); }).find("LAZ is compressed: decompress first (e.g. laszip -i "),
      std::string::npos);
  const std::string empty = Write("empty.las", "");
  EXPECT_EQ(ErrorOf([&] { ReadScan(empty); }), empty + ": empty file");
}

}  // namespace
}  // namespace forestmap::client
