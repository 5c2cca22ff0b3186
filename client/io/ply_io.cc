#include "client/io/ply_io.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::RawScan;

enum class PlyFormat { kAscii, kBinaryLittle, kBinaryBig };

// Scalar types: char uchar short ushort int uint float double (and their int8.. aliases).
enum PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };
constexpr int kTypeSize[] = {1, 1, 2, 2, 4, 4, 4, 8};

// Vertex properties we keep; the rest are skipped.
enum Slot { kX, kY, kZ, kIntensity, kRing, kSkip };

struct PlyProperty {
  PlyType type = kFloat32;
  bool is_list = false;
  PlyType count_type = kUint8;  // lists only
  Slot slot = kSkip;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  size_t data_offset = 0;
  int data_line = 0;  // line number of the first data line (ascii)
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  uint64_t organised_width = 0;
  uint64_t organised_height = 0;
};

bool ParseType(const std::string& name, PlyType* type) {
  static const std::pair<const char*, PlyType> kNames[] = {
      {"char", kInt8},     {"int8", kInt8},       {"uchar", kUint8},    {"uint8", kUint8},
      {"short", kInt16},   {"int16", kInt16},     {"ushort", kUint16},  {"uint16", kUint16},
      {"int", kInt32},     {"int32", kInt32},     {"uint", kUint32},    {"uint32", kUint32},
      {"float", kFloat32}, {"float32", kFloat32}, {"double", kFloat64}, {"float64", kFloat64}};
  for (const auto& [text, value] : kNames) {
    if (name == text) {
      *type = value;
      return true;
    }
  }
  return false;
}

Slot SlotOf(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "x") return kX;
  if (lower == "y") return kY;
  if (lower == "z") return kZ;
  if (lower == "intensity" || lower == "scalar_intensity") return kIntensity;
  if (lower == "ring" || lower == "scalar_ring") return kRing;
  return kSkip;
}

void ParsePropertyLine(std::istringstream& in, const std::string& where, PlyElement* element) {
  PlyProperty property;
  std::string type_name, name;
  in >> type_name;
  if (type_name == "list") {
    std::string count_type;
    in >> count_type >> type_name;
    property.is_list = true;
    if (!ParseType(count_type, &property.count_type) || property.count_type >= kFloat32) {
      Fail(where, StrCat({"invalid list count type '", count_type, "'"}));
    }
  }
  if (!ParseType(type_name, &property.type)) {
    Fail(where, StrCat({"unknown property type '", type_name, "'"}));
  }
  if (!(in >> name)) Fail(where, "property without a name");
  if (!property.is_list) property.slot = SlotOf(name);
  element->properties.push_back(property);
}

PlyHeader ParseHeader(const std::string& bytes, const std::string& path) {
  PlyHeader header;
  size_t pos = 0;
  int line_number = 0;
  bool has_format = false;
  while (true) {
    const size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) Fail(path, "header has no 'end_header' line");
    std::string line = bytes.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = StrCat({path, ":", std::to_string(line_number)});
    if (line_number == 1) {
      if (line != "ply") Fail(where, "not a PLY file (first line is not 'ply')");
      continue;
    }
    std::istringstream in(line);
    std::string key;
    in >> key;
    if (key == "end_header") break;
    if (key == "format") {
      std::string format, version;
      in >> format >> version;
      if (format == "ascii")
        header.format = PlyFormat::kAscii;
      else if (format == "binary_little_endian")
        header.format = PlyFormat::kBinaryLittle;
      else if (format == "binary_big_endian")
        header.format = PlyFormat::kBinaryBig;
      else
        Fail(where, StrCat({"unknown format '", format, "'"}));
      has_format = true;
    } else if (key == "comment" || key == "obj_info") {
      scan_io_internal::ParseOffsetComment(line, where, &header.offset);
      const size_t at = line.find("organised:");
      if (at != std::string::npos) {
        std::istringstream dims(line.substr(at + 10));
        if (!(dims >> header.organised_width >> header.organised_height)) {
          Fail(where, "'organised:' needs width and height");
        }
      }
    } else if (key == "element") {
      PlyElement element;
      if (!(in >> element.name >> element.count)) Fail(where, "element needs a name and a count");
      header.elements.push_back(element);
    } else if (key == "property") {
      if (header.elements.empty()) Fail(where, "property before any element");
      ParsePropertyLine(in, where, &header.elements.back());
    } else if (!key.empty()) {
      Fail(where, StrCat({"unknown header keyword '", key, "'"}));
    }
  }
  if (!has_format) Fail(path, "header has no 'format' line");
  header.data_offset = pos;
  header.data_line = line_number + 1;
  return header;
}

double Decode(const char* p, PlyType type, bool swap) {
  char buffer[8];
  const int size = kTypeSize[type];
  if (swap) {
    std::reverse_copy(p, p + size, buffer);
  } else {
    std::memcpy(buffer, p, size);
  }
  switch (type) {
#define FORESTMAP_PLY_CASE(TAG, T)      \
  case TAG: {                           \
    T v;                                \
    std::memcpy(&v, buffer, sizeof(T)); \
    return static_cast<double>(v);      \
  }
    FORESTMAP_PLY_CASE(kInt8, int8_t)
    FORESTMAP_PLY_CASE(kUint8, uint8_t)
    FORESTMAP_PLY_CASE(kInt16, int16_t)
    FORESTMAP_PLY_CASE(kUint16, uint16_t)
    FORESTMAP_PLY_CASE(kInt32, int32_t)
    FORESTMAP_PLY_CASE(kUint32, uint32_t)
    FORESTMAP_PLY_CASE(kFloat32, float)
    FORESTMAP_PLY_CASE(kFloat64, double)
#undef FORESTMAP_PLY_CASE
  }
  return std::nan("");
}

// Stores a decoded vertex value into its slot of `raw`; false for a ring outside 0..65535.
bool Store(RawScan* raw, size_t i, Slot slot, double value) {
  if (slot <= kZ) {
    raw->xyz[3 * i + slot] = value;
  } else if (slot == kIntensity) {
    raw->intensity[i] = static_cast<float>(value);
  } else if (slot == kRing) {
    if (!(value >= 0 && value <= 65535)) return false;
    raw->ring[i] = static_cast<uint16_t>(value);
  }
  return true;
}

constexpr char kRingRange[] = "ring value out of range 0..65535";

// A list's length as read (any number, NaN or 10^29 included), clamped to [0, limit]: more than
// the data left can hold is reported as truncated data by the caller, never converted beyond
// size_t's range.
size_t ListLength(double count, size_t limit) {
  if (!(count > 0)) return 0;
  return count >= static_cast<double>(limit) ? limit : static_cast<size_t>(count);
}

// Binary: walks every element in order (lists have per-instance lengths), keeping the vertices.
void ReadBinary(const std::string& bytes, const PlyHeader& h, const std::string& path,
                RawScan* raw) {
  const bool swap =
      (h.format == PlyFormat::kBinaryBig) != (std::endian::native == std::endian::big);
  size_t pos = h.data_offset;
  for (const PlyElement& element : h.elements) {
    const bool is_vertex = element.name == "vertex";
    // An element without properties holds no bytes: skipped, not counted through (a count of
    // 10^12 would loop for hours).
    if (element.properties.empty()) continue;
    for (uint64_t i = 0; i < element.count; ++i) {
      for (const PlyProperty& property : element.properties) {
        size_t size = kTypeSize[property.type];
        if (property.is_list) {
          if (pos + kTypeSize[property.count_type] > bytes.size())
            pos = bytes.size() + 1;
          else {
            const double count = Decode(bytes.data() + pos, property.count_type, swap);
            pos += kTypeSize[property.count_type];
            size *= ListLength(count, bytes.size());
          }
        }
        if (pos + size > bytes.size()) {
          Fail(path, StrCat({"byte ", std::to_string(std::min(pos, bytes.size())),
                             ": truncated binary data in element '", element.name, "' ",
                             std::to_string(i), " of ", std::to_string(element.count)}));
        }
        if (is_vertex && property.slot != kSkip) {
          if (!Store(raw, i, property.slot, Decode(bytes.data() + pos, property.type, swap))) {
            Fail(path, StrCat({"byte ", std::to_string(pos), ": ", kRingRange}));
          }
        }
        pos += size;
      }
    }
    if (is_vertex) return;  // what follows (faces) is not needed
  }
}

void ReadAscii(const std::string& bytes, const PlyHeader& h, const std::string& path,
               RawScan* raw) {
  size_t pos = h.data_offset;
  int line_number = h.data_line - 1;
  std::vector<double> values;
  for (const PlyElement& element : h.elements) {
    const bool is_vertex = element.name == "vertex";
    for (uint64_t i = 0; i < element.count; ++i) {
      ++line_number;
      // Built only on failure: a string per line would dominate the reading time.
      auto where = [&] { return StrCat({path, ":", std::to_string(line_number)}); };
      if (pos >= bytes.size()) {
        Fail(where(), StrCat({"unexpected end of file in element '", element.name, "' ",
                              std::to_string(i), " of ", std::to_string(element.count)}));
      }
      size_t end = bytes.find('\n', pos);
      if (end == std::string::npos) end = bytes.size();
      const std::string_view line(bytes.data() + pos, end - pos);
      pos = end + 1;
      if (!is_vertex) continue;
      values.clear();
      size_t at = 0;
      while (at < line.size()) {
        while (at < line.size() && std::isspace(static_cast<unsigned char>(line[at]))) ++at;
        if (at >= line.size()) break;
        double v = 0;
        const auto result = std::from_chars(line.data() + at, line.data() + line.size(), v);
        if (result.ec != std::errc()) {
          Fail(where(), StrCat({"column ", std::to_string(values.size() + 1), ": not a number"}));
        }
        values.push_back(v);
        at = static_cast<size_t>(result.ptr - line.data());
      }
      size_t k = 0;
      for (const PlyProperty& property : element.properties) {
        if (property.is_list) {
          k += 1 + (k < values.size() ? ListLength(values[k], values.size()) : 0);
          continue;
        }
        if (k >= values.size()) {
          Fail(where(), StrCat({"expected more values (vertex ", std::to_string(i), " has ",
                                std::to_string(values.size()), ")"}));
        }
        if (property.slot != kSkip && !Store(raw, i, property.slot, values[k])) {
          Fail(where(), kRingRange);
        }
        ++k;
      }
    }
    if (is_vertex) return;
  }
}

}  // namespace

RawScan ReadPly(const std::string& path) {
  const std::string bytes = scan_io_internal::ReadFileBytes(path);
  const PlyHeader header = ParseHeader(bytes, path);
  const PlyElement* vertex = nullptr;
  for (const PlyElement& element : header.elements) {
    if (element.name != "vertex") continue;
    // The data readers use the first one: a second would describe other columns.
    if (vertex != nullptr) Fail(path, "header has more than one 'element vertex'");
    vertex = &element;
  }
  if (vertex == nullptr) Fail(path, "header has no 'element vertex'");
  bool has[5] = {false, false, false, false, false};
  for (const PlyProperty& property : vertex->properties) {
    if (property.slot != kSkip) has[property.slot] = true;
  }
  if (!has[kX] || !has[kY] || !has[kZ]) Fail(path, "vertex element lacks x, y or z");
  if (vertex->count > 0xFFFFFFFFull) Fail(path, "more than 2^32 vertices are not supported");
  // Each vertex needs at least one byte (binary) or two characters (ascii): a cheap bound that
  // stops a lying header from allocating terabytes.
  if (vertex->count > bytes.size()) {
    Fail(path, StrCat({"point count mismatch: header says ", std::to_string(vertex->count),
                       " vertices, the file has only ", std::to_string(bytes.size()), " bytes"}));
  }
  RawScan raw;
  const size_t n = static_cast<size_t>(vertex->count);
  raw.xyz.resize(3 * n);
  if (has[kIntensity]) raw.intensity.resize(n);
  if (has[kRing]) raw.ring.resize(n);
  raw.width = static_cast<uint32_t>(n);
  if (header.format == PlyFormat::kAscii) {
    ReadAscii(bytes, header, path, &raw);
  } else {
    ReadBinary(bytes, header, path, &raw);
  }
  raw.stated_offset = header.offset;
  if (header.organised_height > 1) {
    if (header.organised_width * header.organised_height != n) {
      Fail(path, "'organised:' width x height does not match the vertex count");
    }
    raw.width = static_cast<uint32_t>(header.organised_width);
    raw.height = static_cast<uint32_t>(header.organised_height);
  }
  return raw;
}

void WritePly(const std::string& path, const algorithms::PointCloud& cloud) {
  const bool has_intensity = !cloud.intensity.empty();
  const bool has_ring = !cloud.ring.empty();
  std::string out = StrCat({"ply\nformat binary_little_endian 1.0\ncomment ForestMap scan; ",
                            scan_io_internal::OffsetComment(cloud.origin), "\n"});
  if (cloud.height > 1) {
    out += StrCat({"comment organised: ", std::to_string(cloud.width), " ",
                   std::to_string(cloud.height), "\n"});
  }
  out += StrCat({"element vertex ", std::to_string(cloud.size()),
                 "\nproperty float x\nproperty float y\nproperty float z\n"});
  if (has_intensity) out += "property float intensity\n";
  if (has_ring) out += "property ushort ring\n";
  out += "end_header\n";
  const size_t step = 12 + (has_intensity ? 4 : 0) + (has_ring ? 2 : 0);
  const size_t start = out.size();
  out.resize(start + step * cloud.size());
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes little endian");
  for (size_t i = 0; i < cloud.size(); ++i) {
    char* p = out.data() + start + i * step;
    std::memcpy(p, cloud.points[i].data(), 12);
    if (has_intensity) std::memcpy(p + 12, &cloud.intensity[i], 4);
    if (has_ring) std::memcpy(p + (has_intensity ? 16 : 12), &cloud.ring[i], 2);
  }
  scan_io_internal::WriteFileBytes(path, out);
}

}  // namespace forestmap::client
