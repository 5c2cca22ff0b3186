#include "client/io/las_crs.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string_view>

#include "client/io/scan_io.h"
#include "client/io/scan_io_internal.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Get;
using scan_io_internal::kVlrHeaderSize;

constexpr size_t kHeaderFields = 104;        // bytes up to and including the VLR count
constexpr size_t kHeader14Fields = 247;      // bytes up to and including LAS 1.4's EVLR count
constexpr size_t kEvlrHeaderSize = 60;       // bytes
constexpr uint64_t kMaxCrsRecord = 1 << 20;  // bytes: a WKT or GeoKeys record is far smaller
constexpr uint16_t kWktRecord = 2112;        // LASF_Projection: OGC coordinate system WKT
constexpr uint16_t kGeoKeyRecord = 34735;    // LASF_Projection: GeoKeyDirectoryTag
constexpr uint16_t kProjectedCsKey = 3072;
constexpr uint16_t kGeographicCsKey = 2048;
constexpr uint16_t kUserDefined = 32767;  // GeoTIFF: "user-defined", no EPSG code

[[noreturn]] void Fail(const std::string& path, size_t byte, const std::string& problem) {
  throw ScanError(path + ": byte " + std::to_string(byte) + ": " + problem);
}

// GeoKeyDirectory: a header of 4 shorts (version, revision, minor, key count), then 4 shorts
// per key (id, location, count, value); location 0 means the value is the short itself.
int EpsgFromGeoKeys(const std::string& bytes, size_t body, size_t length, const std::string& path,
                    size_t at) {
  if (length < 8) Fail(path, at, "GeoKeyDirectory shorter than its header");
  const size_t keys = Get<uint16_t>(bytes, body + 6);
  if (8 + 8 * keys > length) Fail(path, at, "GeoKeyDirectory: more keys than bytes");
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

// Reads `length` bytes at `offset` (the caller has checked they lie inside the file).
using ReadAt = std::function<std::string(size_t offset, size_t length)>;

// What the projection records say so far.
struct Crs {
  std::string wkt;
  int epsg = 0;
  void Record(std::string_view user, uint16_t record, const std::string& body, size_t at,
              const std::string& path) {
    if (user != "LASF_Projection") return;
    if (record == kWktRecord) wkt.assign(body.data(), ::strnlen(body.data(), body.size()));
    if (record == kGeoKeyRecord) epsg = EpsgFromGeoKeys(body, 0, body.size(), path, at);
  }
};

std::string_view UserId(const std::string& record_header) {
  return {record_header.data() + 2, ::strnlen(record_header.data() + 2, 16)};
}

// The variable-length records between the header and the point data.
void ReadVlrs(const std::string& header, size_t file_size, const ReadAt& read, Crs& crs,
              const std::string& path) {
  const size_t header_size = Get<uint16_t>(header, 94);
  const size_t end = std::min<size_t>(Get<uint32_t>(header, 96), file_size);  // point data
  const uint32_t vlr_count = Get<uint32_t>(header, 100);
  size_t pos = header_size;
  for (uint32_t v = 0; v < vlr_count; ++v) {
    if (pos + kVlrHeaderSize > end) Fail(path, pos, "VLR runs past the start of the point data");
    const std::string head = read(pos, kVlrHeaderSize);
    const size_t length = Get<uint16_t>(head, 20);
    const size_t body = pos + kVlrHeaderSize;
    if (body + length > end) Fail(path, pos, "VLR runs past the start of the point data");
    crs.Record(UserId(head), Get<uint16_t>(head, 18), read(body, length), body, path);
    pos = body + length;
  }
}

// LAS 1.4's extended variable-length records after the point data (a WKT may be there).
void ReadEvlrs(const std::string& header, size_t file_size, const ReadAt& read, Crs& crs,
               const std::string& path) {
  if (header.size() < kHeader14Fields || header[24] != 1 || header[25] < 4) return;
  uint64_t pos = Get<uint64_t>(header, 235);
  const uint32_t count = Get<uint32_t>(header, 243);
  for (uint32_t e = 0; e < count; ++e) {
    if (pos > file_size || file_size - pos < kEvlrHeaderSize) {
      Fail(path, pos, "EVLR runs past the end of the file");
    }
    const std::string head = read(pos, kEvlrHeaderSize);
    const uint64_t length = Get<uint64_t>(head, 20);
    const uint64_t body = pos + kEvlrHeaderSize;
    if (length > file_size - body) Fail(path, pos, "EVLR runs past the end of the file");
    const uint16_t record = Get<uint16_t>(head, 18);
    const bool projection =
        UserId(head) == "LASF_Projection" && (record == kWktRecord || record == kGeoKeyRecord);
    if (projection) {
      if (length > kMaxCrsRecord) Fail(path, pos, "a CRS record of over 1 MiB");
      crs.Record(UserId(head), record, read(body, length), body, path);
    }
    pos = body + length;
  }
}

// The CRS of a LAS file of `file_size` bytes read through `read`.
std::string ParseLasCrs(size_t file_size, const ReadAt& read, const std::string& path) {
  if (file_size < kHeaderFields) return "";
  const std::string header = read(0, std::min(file_size, kHeader14Fields));
  if (header.compare(0, 4, "LASF") != 0) return "";
  Crs crs;
  ReadVlrs(header, file_size, read, crs, path);
  ReadEvlrs(header, file_size, read, crs, path);
  if (!crs.wkt.empty()) return crs.wkt;
  return crs.epsg > 0 ? "EPSG:" + std::to_string(crs.epsg) : "";
}

}  // namespace

std::string LasCrsFromBytes(const std::string& bytes, const std::string& path) {
  return ParseLasCrs(
      bytes.size(), [&](size_t offset, size_t length) { return bytes.substr(offset, length); },
      path);
}

std::string ReadLasCrs(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".las") return "";
  // Only the header and the records are read, not the points (LAS files run to gigabytes).
  std::ifstream in(path, std::ios::binary);
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path, error);
  if (!in || error) throw ScanError(path + ": cannot read: " + error.message());
  return ParseLasCrs(
      static_cast<size_t>(size),
      [&](size_t offset, size_t length) {
        std::string bytes(length, '\0');
        in.seekg(static_cast<std::streamoff>(offset));
        in.read(bytes.data(), static_cast<std::streamsize>(length));
        if (!in) throw ScanError(path + ": byte " + std::to_string(offset) + ": cannot read");
        return bytes;
      },
      path);
}

}  // namespace forestmap::client
