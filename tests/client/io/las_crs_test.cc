// The CRS of LAS files: GeoKeys and WKT VLRs (ASPRS LAS 1.4 R15, section 2.5).
#include "client/io/las_crs.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "client/io/scan_io.h"

namespace forestmap::client {
namespace {

constexpr size_t kHeaderSize = 227;  // LAS 1.2

template <typename T>
void Put(std::string& bytes, size_t offset, T value) {
  std::memcpy(bytes.data() + offset, &value, sizeof(T));
}

std::string Vlr(const std::string& user, uint16_t record, const std::string& body) {
  std::string vlr(54, '\0');
  std::memcpy(vlr.data() + 2, user.data(), user.size());
  Put<uint16_t>(vlr, 18, record);
  Put<uint16_t>(vlr, 20, static_cast<uint16_t>(body.size()));
  return vlr + body;
}

// A LAS 1.2 file without points whose VLRs are `vlrs`.
std::string Las(const std::vector<std::string>& vlrs) {
  std::string bytes(kHeaderSize, '\0');
  std::memcpy(bytes.data(), "LASF", 4);
  bytes[24] = 1;
  bytes[25] = 2;
  size_t size = kHeaderSize;
  for (const std::string& vlr : vlrs) size += vlr.size();
  Put<uint16_t>(bytes, 94, kHeaderSize);
  Put<uint32_t>(bytes, 96, static_cast<uint32_t>(size));
  Put<uint32_t>(bytes, 100, static_cast<uint32_t>(vlrs.size()));
  Put<uint16_t>(bytes, 105, 20);
  for (const std::string& vlr : vlrs) bytes += vlr;
  return bytes;
}

// GeoKeyDirectory with the given (id, value) keys stored inline.
std::string GeoKeys(const std::vector<std::pair<uint16_t, uint16_t>>& keys) {
  std::string body(8 + 8 * keys.size(), '\0');
  Put<uint16_t>(body, 0, 1);
  Put<uint16_t>(body, 2, 1);
  Put<uint16_t>(body, 6, static_cast<uint16_t>(keys.size()));
  for (size_t k = 0; k < keys.size(); ++k) {
    Put<uint16_t>(body, 8 + 8 * k, keys[k].first);
    Put<uint16_t>(body, 8 + 8 * k + 4, 1);
    Put<uint16_t>(body, 8 + 8 * k + 6, keys[k].second);
  }
  return body;
}

TEST(LasCrsTest, ProjectedGeoKeyGivesTheEpsgCode) {
  // GTModelType 1 (projected), GTRasterType, ProjectedCSTypeGeoKey 2959.
  const std::string las =
      Las({Vlr("LASF_Projection", 34735, GeoKeys({{1024, 1}, {1025, 1}, {3072, 2959}}))});
  EXPECT_EQ(LasCrsFromBytes(las, "a.las"), "EPSG:2959");
}

TEST(LasCrsTest, GeographicGeoKeyAndUserDefinedCodes) {
  EXPECT_EQ(LasCrsFromBytes(Las({Vlr("LASF_Projection", 34735, GeoKeys({{2048, 4617}}))}), "a"),
            "EPSG:4617");
  EXPECT_EQ(LasCrsFromBytes(Las({Vlr("LASF_Projection", 34735, GeoKeys({{3072, 32767}}))}), "a"),
            "");
}

TEST(LasCrsTest, WktVlrWinsOverGeoKeys) {
  const std::string wkt = "PROJCS[\"NAD83(CSRS) / UTM zone 18N\",AUTHORITY[\"EPSG\",\"2959\"]]";
  const std::string las = Las({Vlr("LASF_Projection", 34735, GeoKeys({{3072, 32617}})),
                               Vlr("LASF_Projection", 2112, wkt + std::string(1, '\0'))});
  EXPECT_EQ(LasCrsFromBytes(las, "a.las"), wkt);
}

TEST(LasCrsTest, NoCrsAndBrokenVlrs) {
  EXPECT_EQ(LasCrsFromBytes(Las({}), "a.las"), "");
  EXPECT_EQ(LasCrsFromBytes("not a las file at all, longer than a header......................"
                            "...........................................................",
                            "a.las"),
            "");
  std::string las = Las({Vlr("LASF_Projection", 34735, GeoKeys({{3072, 2959}}))});
  Put<uint16_t>(las, kHeaderSize + 20, 5000);  // the VLR claims more bytes than there are
  try {
    LasCrsFromBytes(las, "broken.las");
    FAIL() << "no error";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.las: byte 227: VLR runs past"), std::string::npos)
        << e.what();
  }
}

// A LAS 1.4 file without points or VLRs whose EVLRs (after the points) are `evlrs`, each a WKT.
std::string Las14WithEvlrs(const std::vector<std::string>& wkts) {
  constexpr size_t kHeader14 = 375;
  std::string bytes(kHeader14, '\0');
  std::memcpy(bytes.data(), "LASF", 4);
  bytes[24] = 1;
  bytes[25] = 4;
  Put<uint16_t>(bytes, 94, kHeader14);
  Put<uint32_t>(bytes, 96, kHeader14);
  Put<uint64_t>(bytes, 235, kHeader14);
  Put<uint32_t>(bytes, 243, static_cast<uint32_t>(wkts.size()));
  for (const std::string& wkt : wkts) {
    std::string evlr(60, '\0');
    std::memcpy(evlr.data() + 2, "LASF_Projection", 15);
    Put<uint16_t>(evlr, 18, 2112);
    Put<uint64_t>(evlr, 20, wkt.size());
    bytes += evlr + wkt;
  }
  return bytes;
}

TEST(LasCrsTest, Las14WktInAnExtendedVlr) {
  const std::string wkt = "PROJCS[\"NAD83(CSRS) / UTM zone 18N\",AUTHORITY[\"EPSG\",\"2959\"]]";
  const std::string las = Las14WithEvlrs({wkt});
  EXPECT_EQ(LasCrsFromBytes(las, "a.las"), wkt);
  // From a file too: only the header and the records are read.
  const std::string path = ::testing::TempDir() + "/evlr_crs_test.las";
  std::ofstream(path, std::ios::binary) << las;
  EXPECT_EQ(ReadLasCrs(path), wkt);
  std::remove(path.c_str());

  std::string broken = las;
  Put<uint64_t>(broken, 375 + 20, uint64_t{1} << 62);  // past the end of the file
  try {
    LasCrsFromBytes(broken, "broken.las");
    FAIL() << "no error";
  } catch (const ScanError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.las: byte 375: EVLR runs past the end"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace forestmap::client
