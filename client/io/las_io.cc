#include "client/io/las_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>

#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::Get;
using scan_io_internal::kVlrHeaderSize;
using scan_io_internal::RawScan;

// Public header block sizes by minor version (LAS 1.0-1.2: 227, 1.3: 235, 1.4: 375 bytes).
constexpr size_t kHeaderSize12 = 227;
constexpr size_t kHeaderSize13 = 235;
constexpr size_t kHeaderSize14 = 375;
constexpr size_t kExtraBytesDescriptorSize = 192;
// Bytes of the standard part of a point record, by point data format 0-10.
constexpr uint16_t kFormatSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

std::string At(size_t byte) { return StrCat({"byte ", std::to_string(byte), ": "}); }

std::string Lower(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// Fixed-width, NUL-padded string field.
std::string_view FixedString(const std::string& bytes, size_t offset, size_t size) {
  std::string_view text(bytes.data() + offset, size);
  return text.substr(0, text.find('\0'));
}

struct LasHeader {
  int minor = 0;
  size_t header_size = 0;
  size_t point_offset = 0;
  uint32_t vlr_count = 0;
  int format = 0;
  size_t record_length = 0;
  uint64_t count = 0;
  double scale[3] = {1, 1, 1};
  double offset[3] = {0, 0, 0};
};

// A numeric attribute in the extra bytes of each point record (LAS 1.4 R15, 2.6 / table 24).
struct ExtraAttribute {
  size_t offset = 0;  // bytes from the start of the point record
  int type = 0;       // 1..10: uchar char ushort short ulong long ulonglong longlong float double
  double scale = 1.0;
  double add = 0.0;
};

const std::string kLazMessage =
    "LAZ is compressed: decompress first (e.g. laszip -i X.laz -o X.las)";

LasHeader ParseHeader(const std::string& bytes, const std::string& path) {
  if (bytes.size() < kHeaderSize12) {
    Fail(path, StrCat({"file too short for a LAS header (", std::to_string(bytes.size()),
                       " bytes, need 227)"}));
  }
  if (bytes.compare(0, 4, "LASF") != 0) Fail(path, "byte 0: wrong signature (not 'LASF')");
  LasHeader h;
  const int major = static_cast<uint8_t>(bytes[24]);
  h.minor = static_cast<uint8_t>(bytes[25]);
  if (major != 1 || h.minor > 4) {
    Fail(path, StrCat({At(24), "unsupported LAS version ", std::to_string(major), ".",
                       std::to_string(h.minor), " (expected 1.0 to 1.4)"}));
  }
  h.header_size = Get<uint16_t>(bytes, 94);
  const size_t minimum = h.minor == 4   ? kHeaderSize14
                         : h.minor == 3 ? kHeaderSize13
                                        : kHeaderSize12;
  if (h.header_size < minimum || h.header_size > bytes.size()) {
    Fail(path, StrCat({At(94), "header size ", std::to_string(h.header_size), " invalid for LAS 1.",
                       std::to_string(h.minor), " (need ", std::to_string(minimum),
                       " bytes, file has ", std::to_string(bytes.size()), ")"}));
  }
  h.point_offset = Get<uint32_t>(bytes, 96);
  h.vlr_count = Get<uint32_t>(bytes, 100);
  const uint8_t format_byte = static_cast<uint8_t>(bytes[104]);
  if (format_byte & 0xC0) Fail(path, kLazMessage);  // LASzip sets the top bits
  h.format = format_byte;
  const int max_format = h.minor == 4 ? 10 : h.minor == 3 ? 5 : h.minor == 2 ? 3 : 1;
  if (h.format > max_format) {
    Fail(path, StrCat({At(104), "point data format ", std::to_string(h.format),
                       " is not defined for LAS 1.", std::to_string(h.minor), " (0 to ",
                       std::to_string(max_format), ")"}));
  }
  h.record_length = Get<uint16_t>(bytes, 105);
  if (h.record_length < kFormatSize[h.format]) {
    Fail(path, StrCat({At(105), "point record length ", std::to_string(h.record_length),
                       " is shorter than format ", std::to_string(h.format), "'s ",
                       std::to_string(kFormatSize[h.format]), " bytes"}));
  }
  h.count = Get<uint32_t>(bytes, 107);
  if (h.minor == 4) {
    const uint64_t count64 = Get<uint64_t>(bytes, 247);
    if (h.count != 0 && count64 != 0 && count64 != h.count) {
      Fail(path, StrCat({At(247), "point count mismatch: legacy count ", std::to_string(h.count),
                         ", 64-bit count ", std::to_string(count64)}));
    }
    if (count64 != 0) h.count = count64;
  }
  for (int a = 0; a < 3; ++a) {
    h.scale[a] = Get<double>(bytes, 131 + 8 * a);
    h.offset[a] = Get<double>(bytes, 155 + 8 * a);
    if (!std::isfinite(h.scale[a]) || h.scale[a] == 0.0 || !std::isfinite(h.offset[a])) {
      Fail(path, StrCat({At(131 + 8 * a), "invalid scale or offset for axis ",
                         std::string(1, static_cast<char>('x' + a))}));
    }
  }
  return h;
}

int ExtraTypeSize(int type, int options) {
  static constexpr int kSize[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  if (type == 0) return options;  // undocumented bytes: `options` holds their count
  if (type <= 10) return kSize[type];
  if (type <= 30) return kSize[(type - 1) % 10 + 1] * ((type - 1) / 10 + 1);  // deprecated arrays
  return -1;
}

// Walks the VLRs: rejects LASzip data, and finds the "ring" extra-bytes attribute (if any).
bool FindRing(const std::string& bytes, const LasHeader& h, const std::string& path,
              ExtraAttribute* ring) {
  size_t pos = h.header_size;
  size_t extra_offset = kFormatSize[h.format];
  bool found = false;
  for (uint32_t v = 0; v < h.vlr_count; ++v) {
    if (pos + kVlrHeaderSize > h.point_offset) {
      Fail(path, StrCat({At(pos), "VLR ", std::to_string(v), " of ", std::to_string(h.vlr_count),
                         " runs past the start of the point data"}));
    }
    const std::string_view user = FixedString(bytes, pos + 2, 16);
    const uint16_t record_id = Get<uint16_t>(bytes, pos + 18);
    const size_t length = Get<uint16_t>(bytes, pos + 20);
    const size_t body = pos + kVlrHeaderSize;
    if (body + length > h.point_offset) {
      Fail(path, StrCat({At(pos), "VLR '", std::string(user), "' (", std::to_string(length),
                         " bytes) runs past the start of the point data"}));
    }
    if (user == "laszip encoded") Fail(path, kLazMessage);
    if (user == "LASF_Spec" && record_id == 4) {
      for (size_t d = body; d + kExtraBytesDescriptorSize <= body + length;
           d += kExtraBytesDescriptorSize) {
        const int type = static_cast<uint8_t>(bytes[d + 2]);
        const int options = static_cast<uint8_t>(bytes[d + 3]);
        const int size = ExtraTypeSize(type, options);
        if (size < 0)
          Fail(path, StrCat({At(d + 2), "unknown extra bytes data type ", std::to_string(type)}));
        if (!found && type >= 1 && type <= 10 && Lower(FixedString(bytes, d + 4, 32)) == "ring") {
          ring->offset = extra_offset;
          ring->type = type;
          if (options & 8) ring->scale = Get<double>(bytes, d + 112);
          if (options & 16) ring->add = Get<double>(bytes, d + 136);
          found = true;
        }
        extra_offset += static_cast<size_t>(size);
      }
      if (extra_offset > h.record_length) {
        Fail(path, StrCat({At(body), "extra bytes attributes need ", std::to_string(extra_offset),
                           " bytes per point, the record has ", std::to_string(h.record_length)}));
      }
    }
    pos = body + length;
  }
  return found;
}

double ExtraValue(const char* p, int type) {
  switch (type) {
#define FORESTMAP_LAS_CASE(N, T)   \
  case N: {                        \
    T v;                           \
    std::memcpy(&v, p, sizeof(T)); \
    return static_cast<double>(v); \
  }
    FORESTMAP_LAS_CASE(1, uint8_t)
    FORESTMAP_LAS_CASE(2, int8_t)
    FORESTMAP_LAS_CASE(3, uint16_t)
    FORESTMAP_LAS_CASE(4, int16_t)
    FORESTMAP_LAS_CASE(5, uint32_t)
    FORESTMAP_LAS_CASE(6, int32_t)
    FORESTMAP_LAS_CASE(7, uint64_t)
    FORESTMAP_LAS_CASE(8, int64_t)
    FORESTMAP_LAS_CASE(9, float)
    FORESTMAP_LAS_CASE(10, double)
#undef FORESTMAP_LAS_CASE
    default:
      return std::nan("");
  }
}

}  // namespace

RawScan ReadLas(const std::string& path) {
  const std::string bytes = scan_io_internal::ReadFileBytes(path);
  const LasHeader h = ParseHeader(bytes, path);
  if (h.point_offset < h.header_size || h.point_offset > bytes.size()) {
    Fail(path, StrCat({At(96), "offset to point data ", std::to_string(h.point_offset),
                       " is outside the file (header ", std::to_string(h.header_size),
                       " bytes, file ", std::to_string(bytes.size()), " bytes)"}));
  }
  ExtraAttribute ring;
  const bool has_ring = FindRing(bytes, h, path, &ring);
  const uint64_t available = bytes.size() - h.point_offset;
  if (h.count > available / h.record_length) {
    Fail(path, StrCat({At(h.point_offset), "truncated point data: the header says ",
                       std::to_string(h.count), " points of ", std::to_string(h.record_length),
                       " bytes, the file holds ", std::to_string(available / h.record_length)}));
  }
  if (h.count > 0xFFFFFFFFull) Fail(path, "more than 2^32 points are not supported");
  RawScan raw;
  const size_t n = static_cast<size_t>(h.count);
  raw.width = static_cast<uint32_t>(n);
  raw.xyz.resize(3 * n);
  raw.intensity.resize(n);
  if (has_ring) raw.ring.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const size_t record = h.point_offset + i * h.record_length;
    for (int a = 0; a < 3; ++a) {
      // X*scale+offset in double; the origin is subtracted later, still in double.
      raw.xyz[3 * i + a] = Get<int32_t>(bytes, record + 4 * a) * h.scale[a] + h.offset[a];
    }
    raw.intensity[i] = Get<uint16_t>(bytes, record + 12);
    if (has_ring) {
      const double value =
          ExtraValue(bytes.data() + record + ring.offset, ring.type) * ring.scale + ring.add;
      if (!(value >= 0.0 && value <= 65535.0)) {
        Fail(path, StrCat({At(record + ring.offset), "point ", std::to_string(i),
                           ": ring value out of range 0..65535"}));
      }
      raw.ring[i] = static_cast<uint16_t>(std::lround(value));
    }
  }
  return raw;
}

}  // namespace forestmap::client
