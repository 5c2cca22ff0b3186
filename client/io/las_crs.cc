#include "client/io/las_crs.h"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string_view>

#include "client/io/scan_io.h"
#include "client/io/scan_io_internal.h"

namespace forestmap::client {
namespace {

constexpr size_t kHeaderFields = 104;      // bytes up to and including the VLR count
constexpr size_t kVlrHeaderSize = 54;      // bytes
constexpr uint16_t kWktRecord = 2112;      // LASF_Projection: OGC coordinate system WKT
constexpr uint16_t kGeoKeyRecord = 34735;  // LASF_Projection: GeoKeyDirectoryTag
constexpr uint16_t kProjectedCsKey = 3072;
constexpr uint16_t kGeographicCsKey = 2048;
constexpr uint16_t kUserDefined = 32767;  // GeoTIFF: "user-defined", no EPSG code

template <typename T>
T Get(const std::string& bytes, size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

[[noreturn]] void Fail(const std::string& path, size_t byte, const std::string& problem) {
  throw ScanError(path + ": byte " + std::to_string(byte) + ": " + problem);
}

// GeoKeyDirectory: a header of 4 shorts (version, revision, minor, key count), then 4 shorts
// per key (id, location, count, value); location 0 means the value is the short itself.
int EpsgFromGeoKeys(const std::string& bytes, size_t body, size_t length, const std::string& path) {
  if (length < 8) Fail(path, body, "GeoKeyDirectory shorter than its header");
  const size_t keys = Get<uint16_t>(bytes, body + 6);
  if (8 + 8 * keys > length) Fail(path, body, "GeoKeyDirectory: more keys than bytes");
  int geographic = 0;
  for (size_t k = 0; k < keys; ++k) {
    const size_t key = body + 8 + 8 * k;
    const uint16_t id = Get<uint16_t>(bytes, key);
    const uint16_t location = Get<uint16_t>(bytes, key + 2);
    const uint16_t value = Get<uint16_t>(bytes, key + 6);
    if (location != 0 || value == 0 || value == kUserDefined) continue;
    if (id == kProjectedCsKey) return value;
    if (id == kGeographicCsKey) geographic = value;
  }
  return geographic;
}

}  // namespace

std::string LasCrsFromBytes(const std::string& bytes, const std::string& path) {
  if (bytes.size() < kHeaderFields || bytes.compare(0, 4, "LASF") != 0) return "";
  const size_t header_size = Get<uint16_t>(bytes, 94);
  const size_t point_offset = Get<uint32_t>(bytes, 96);
  const uint32_t vlr_count = Get<uint32_t>(bytes, 100);
  const size_t end = std::min(point_offset, bytes.size());
  size_t pos = header_size;
  std::string wkt;
  int epsg = 0;
  for (uint32_t v = 0; v < vlr_count; ++v) {
    if (pos + kVlrHeaderSize > end) Fail(path, pos, "VLR runs past the start of the point data");
    const std::string_view user(bytes.data() + pos + 2, ::strnlen(bytes.data() + pos + 2, 16));
    const uint16_t record = Get<uint16_t>(bytes, pos + 18);
    const size_t length = Get<uint16_t>(bytes, pos + 20);
    const size_t body = pos + kVlrHeaderSize;
    if (body + length > end) Fail(path, pos, "VLR runs past the start of the point data");
    if (user == "LASF_Projection" && record == kWktRecord) {
      wkt.assign(bytes.data() + body, ::strnlen(bytes.data() + body, length));
    }
    if (user == "LASF_Projection" && record == kGeoKeyRecord) {
      epsg = EpsgFromGeoKeys(bytes, body, length, path);
    }
    pos = body + length;
  }
  if (!wkt.empty()) return wkt;
  return epsg > 0 ? "EPSG:" + std::to_string(epsg) : "";
}

std::string ReadLasCrs(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".las") return "";
  return LasCrsFromBytes(scan_io_internal::ReadFileBytes(path), path);
}

}  // namespace forestmap::client
