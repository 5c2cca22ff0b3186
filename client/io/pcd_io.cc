// The PCL adapter: the only file that includes PCL. PCL parses the point data (ascii, binary and
// LZF binary_compressed); this file checks the header first, because PCL reports problems by
// printing them and returning -1, and we want errors that name the field and the place.

#include "client/io/pcd_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::RawScan;

struct PcdHeader {
  std::vector<std::string> fields;
  std::vector<int> sizes;
  std::vector<char> types;
  std::vector<int> counts;
  uint64_t width = 0;
  uint64_t height = 1;
  uint64_t points = 0;
  bool has_width = false;
  bool has_points = false;
  std::string data;          // ascii, binary or binary_compressed
  uint64_t data_offset = 0;  // bytes from the file start to the first data byte
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // from an "offset subtracted:" comment
};

std::vector<std::string> Tokens(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string token; in >> token;) out.push_back(token);
  return out;
}

uint64_t ParseCount(const std::string& text, const std::string& where, const char* key) {
  uint64_t value = 0;
  const char* end = text.data() + text.size();
  const auto result = std::from_chars(text.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end) {
    Fail(where, StrCat({key, " must be a non-negative integer, got '", text, "'"}));
  }
  return value;
}

// Reads one header keyword line into `header`; `where` is "FILE:LINE".
void ParseHeaderLine(const std::vector<std::string>& tokens, const std::string& where,
                     PcdHeader* header) {
  const std::string& key = tokens[0];
  const size_t n = tokens.size() - 1;
  auto single = [&]() -> const std::string& {
    if (n != 1) Fail(where, StrCat({key, " needs exactly one value"}));
    return tokens[1];
  };
  if (key == "FIELDS" || key == "COLUMNS") {
    header->fields.assign(tokens.begin() + 1, tokens.end());
  } else if (key == "SIZE") {
    for (size_t i = 1; i <= n; ++i) {
      const uint64_t size = ParseCount(tokens[i], where, "SIZE");
      if (size > 8) Fail(where, StrCat({"SIZE must be 1, 2, 4 or 8 bytes, got ", tokens[i]}));
      header->sizes.push_back(static_cast<int>(size));
    }
  } else if (key == "TYPE") {
    for (size_t i = 1; i <= n; ++i) {
      if (tokens[i].size() != 1 ||
          std::string_view("IUF").find(tokens[i][0]) == std::string::npos) {
        Fail(where, StrCat({"TYPE must be I, U or F, got '", tokens[i], "'"}));
      }
      header->types.push_back(tokens[i][0]);
    }
  } else if (key == "COUNT") {
    constexpr uint64_t kMaxCount = 1 << 16;  // values of one field in one point
    for (size_t i = 1; i <= n; ++i) {
      const uint64_t count = ParseCount(tokens[i], where, "COUNT");
      if (count > kMaxCount) {
        Fail(where, StrCat({"COUNT ", tokens[i], " is over ", std::to_string(kMaxCount),
                            " values per field (not a point cloud?)"}));
      }
      header->counts.push_back(static_cast<int>(count));
    }
  } else if (key == "WIDTH") {
    header->width = ParseCount(single(), where, "WIDTH");
    header->has_width = true;
  } else if (key == "HEIGHT") {
    header->height = ParseCount(single(), where, "HEIGHT");
  } else if (key == "POINTS") {
    header->points = ParseCount(single(), where, "POINTS");
    header->has_points = true;
  } else if (key == "DATA") {
    header->data = single();
    if (header->data != "ascii" && header->data != "binary" &&
        header->data != "binary_compressed") {
      Fail(where,
           StrCat({"DATA must be ascii, binary or binary_compressed, got '", header->data, "'"}));
    }
  } else if (key != "VERSION" && key != "VIEWPOINT") {
    Fail(where, StrCat({"unknown header keyword '", key, "'"}));
  }
}

void CheckHeader(const PcdHeader& h, const std::string& path) {
  const size_t n = h.fields.size();
  if (n == 0) Fail(path, "header has no FIELDS line");
  if (h.sizes.size() != n) Fail(path, "header SIZE does not have one entry per field");
  if (h.types.size() != n) Fail(path, "header TYPE does not have one entry per field");
  if (!h.counts.empty() && h.counts.size() != n) {
    Fail(path, "header COUNT does not have one entry per field");
  }
  for (size_t i = 0; i < n; ++i) {
    const int size = h.sizes[i];
    const bool ok = h.types[i] == 'F' ? (size == 4 || size == 8)
                                      : (size == 1 || size == 2 || size == 4 || size == 8);
    if (!ok) {
      Fail(path, StrCat({"field '", h.fields[i], "': TYPE ", std::string(1, h.types[i]),
                         " cannot have SIZE ", std::to_string(size)}));
    }
  }
  for (size_t i = 0; i < h.counts.size(); ++i) {
    // PCL drops a field with COUNT 0, so it would not be there to read.
    if (h.counts[i] < 1)
      Fail(path, StrCat({"field '", h.fields[i], "': COUNT must be at least 1"}));
  }
  for (const char* axis : {"x", "y", "z"}) {
    bool found = false;
    for (size_t i = 0; i < n; ++i) found = found || h.fields[i] == axis;
    if (!found) Fail(path, StrCat({"header FIELDS has no '", axis, "' field"}));
  }
  if (!h.has_width) Fail(path, "header has no WIDTH line");
  if (h.data.empty()) Fail(path, "header has no DATA line");
  if (h.has_points && h.points != h.width * h.height) {
    Fail(path, StrCat({"point count mismatch: POINTS ", std::to_string(h.points),
                       " but WIDTH x HEIGHT = ", std::to_string(h.width * h.height)}));
  }
  if (h.width * h.height > std::numeric_limits<uint32_t>::max()) {
    Fail(path, "too many points");
  }
}

// PCL reads on after the DATA line while lines are empty, comments, or start with a header
// keyword (prefix match; a later DATA wins). Data that begins like that would be read by PCL
// differently from this header (a later "DATA binary_compressed" whose size word asks for a GB), so
// it is refused.
void CheckDataStart(std::istream& in, int line_number, const std::string& path) {
  static constexpr const char* kKeywords[] = {"VERSION",   "FIELDS", "COLUMNS", "SIZE",
                                              "TYPE",      "COUNT",  "WIDTH",   "HEIGHT",
                                              "VIEWPOINT", "POINTS", "DATA"};
  constexpr size_t kMaxLook = 4096;  // bytes of a data line looked at
  for (int n = line_number + 1; in; ++n) {
    std::string line;
    for (int c; line.size() < kMaxLook && (c = in.get()) != EOF && c != '\n';) {
      line += static_cast<char>(c);
    }
    const std::vector<std::string> tokens = Tokens(line);
    if (tokens.empty() && !line.empty()) return;  // PCL stops at white space
    if (tokens.empty() || tokens[0][0] == '#') continue;
    for (const char* keyword : kKeywords) {
      if (tokens[0].rfind(keyword, 0) == 0) {
        Fail(StrCat({path, ":", std::to_string(n)}),
             StrCat({"data after the DATA line starts with header keyword '", keyword,
                     "' (PCL would read it as header; a second header?)"}));
      }
    }
    return;
  }
}

// Parses the header by hand (PCL skips comments, and we want the offset comment and our own
// messages), and checks that binary data is long enough before PCL maps it.
PcdHeader ReadHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open file for reading");
  PcdHeader header;
  std::string line;
  int line_number = 0;
  uint64_t consumed = 0;
  while (header.data.empty() && std::getline(in, line)) {
    ++line_number;
    consumed += line.size() + 1;
    if (line.size() > 1 << 16)
      Fail(path, StrCat({"line ", std::to_string(line_number),
                         ": header line too long (not a PCD file?)"}));
    const std::string where = StrCat({path, ":", std::to_string(line_number)});
    // PCL 1.13 dereferences null on a header line of only white space (" ", "\t", a CRLF "\r").
    if (!line.empty() && line[0] != '#' && Tokens(line).empty()) {
      Fail(where, "header line of only white space (PCL cannot read it; make it empty)");
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] == '#') {
      scan_io_internal::ParseOffsetComment(line, where, &header.offset);
      continue;
    }
    const std::vector<std::string> tokens = Tokens(line);
    if (tokens.empty()) continue;
    ParseHeaderLine(tokens, where, &header);
  }
  if (line_number == 0) Fail(path, "empty file");
  if (!header.data.empty()) CheckDataStart(in, line_number, path);
  header.data_offset = consumed;
  CheckHeader(header, path);
  if (!header.has_points) header.points = header.width * header.height;
  return header;
}

uint64_t PointStep(const PcdHeader& h) {
  uint64_t step = 0;
  for (size_t i = 0; i < h.fields.size(); ++i) {
    step += static_cast<uint64_t>(h.sizes[i]) * (h.counts.empty() ? 1 : h.counts[i]);
  }
  return step;
}

void CheckDataLength(const PcdHeader& h, const std::string& path) {
  const uint64_t file_size = std::filesystem::file_size(path);
  const uint64_t available = file_size > h.data_offset ? file_size - h.data_offset : 0;
  const uint64_t needed = h.points * PointStep(h);
  // PCL allocates points x point step before it reads ascii data, so a header must not promise
  // more values than the file has bytes (each value takes at least one).
  uint64_t values = 0;
  for (size_t i = 0; i < h.fields.size(); ++i) values += h.counts.empty() ? 1 : h.counts[i];
  if (h.data == "ascii" && h.points * values > available) {
    Fail(path, StrCat({"byte ", std::to_string(h.data_offset), ": ", std::to_string(h.points),
                       " points of ", std::to_string(values), " values cannot fit in the ",
                       std::to_string(available), " bytes of ascii data (truncated file?)"}));
  }
  if (h.data == "binary" && available < needed) {
    Fail(path, StrCat({"byte ", std::to_string(h.data_offset), ": truncated binary data: ",
                       std::to_string(h.points), " points need ", std::to_string(needed),
                       " bytes, the file has ", std::to_string(available)}));
  }
  // Size words are checked whenever they are there: with no points the uncompressed size must be
  // 0 too, or PCL allocates what the word says (2.4 GB for a 217-byte file).
  if (h.data == "binary_compressed" && (h.points > 0 || available >= 8)) {
    uint32_t sizes[2] = {0, 0};
    std::ifstream in(path, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    if (available < 8 || !in.read(reinterpret_cast<char*>(sizes), 8)) {
      Fail(path, StrCat({"byte ", std::to_string(h.data_offset),
                         ": truncated binary_compressed data (no size words)"}));
    }
    if (sizes[1] != needed || sizes[0] > available - 8) {
      Fail(path,
           StrCat({"byte ", std::to_string(h.data_offset), ": binary_compressed sizes (compressed ",
                   std::to_string(sizes[0]), ", uncompressed ", std::to_string(sizes[1]),
                   ") do not fit ", std::to_string(needed), " bytes of points and ",
                   std::to_string(available - 8), " bytes in the file"}));
    }
  }
}

// PCL prints its errors to the console; library code must not print, and we report every
// failure ourselves. Silenced once for the process (not saved and restored around each read:
// that would race between threads), which is safe because this adapter is PCL's only user.
void SilencePcl() {
  static std::once_flag once;
  std::call_once(once, [] { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); });
}

double ValueAt(const uint8_t* p, uint8_t datatype) {
  using F = pcl::PCLPointField;
  switch (datatype) {
#define FORESTMAP_PCD_CASE(TAG, T) \
  case F::TAG: {                   \
    T v;                           \
    std::memcpy(&v, p, sizeof(T)); \
    return static_cast<double>(v); \
  }
    FORESTMAP_PCD_CASE(INT8, int8_t)
    FORESTMAP_PCD_CASE(UINT8, uint8_t)
    FORESTMAP_PCD_CASE(INT16, int16_t)
    FORESTMAP_PCD_CASE(UINT16, uint16_t)
    FORESTMAP_PCD_CASE(INT32, int32_t)
    FORESTMAP_PCD_CASE(UINT32, uint32_t)
    FORESTMAP_PCD_CASE(INT64, int64_t)
    FORESTMAP_PCD_CASE(UINT64, uint64_t)
    FORESTMAP_PCD_CASE(FLOAT32, float)
    FORESTMAP_PCD_CASE(FLOAT64, double)
#undef FORESTMAP_PCD_CASE
    default:
      return std::numeric_limits<double>::quiet_NaN();
  }
}

const pcl::PCLPointField* FindField(const pcl::PCLPointCloud2& cloud, const char* name) {
  for (const auto& field : cloud.fields) {
    if (field.name == name) return &field;
  }
  return nullptr;
}

// Copies x y z (float or double, kept as double), intensity and ring out of PCL's byte blob.
RawScan Convert(const pcl::PCLPointCloud2& cloud, const std::string& path) {
  const pcl::PCLPointField* axes[3] = {FindField(cloud, "x"), FindField(cloud, "y"),
                                       FindField(cloud, "z")};
  const pcl::PCLPointField* intensity = FindField(cloud, "intensity");
  const pcl::PCLPointField* ring = FindField(cloud, "ring");
  // The header was checked; these guard against PCL reading it differently.
  if (axes[0] == nullptr || axes[1] == nullptr || axes[2] == nullptr) {
    Fail(path, "PCL returned no x, y or z field");
  }
  for (const pcl::PCLPointField* field : {axes[0], axes[1], axes[2], intensity, ring}) {
    if (field != nullptr && field->offset + pcl::getFieldSize(field->datatype) > cloud.point_step) {
      Fail(path, StrCat({"field '", field->name, "' lies outside PCL's point record"}));
    }
  }
  const size_t n = static_cast<size_t>(cloud.width) * cloud.height;
  if (cloud.data.size() < n * cloud.point_step) Fail(path, "PCL returned too little data");
  RawScan raw;
  raw.width = cloud.width;
  raw.height = cloud.height;
  raw.xyz.resize(3 * n);
  if (intensity != nullptr) raw.intensity.resize(n);
  if (ring != nullptr) raw.ring.resize(n);
  const uint8_t* base = cloud.data.data();
  const bool float_xyz = axes[0]->datatype == pcl::PCLPointField::FLOAT32 &&
                         axes[1]->datatype == pcl::PCLPointField::FLOAT32 &&
                         axes[2]->datatype == pcl::PCLPointField::FLOAT32;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* point = base + i * cloud.point_step;
    for (int a = 0; a < 3; ++a) {
      if (float_xyz) {  // the common case, without the type switch
        float v;
        std::memcpy(&v, point + axes[a]->offset, sizeof(v));
        raw.xyz[3 * i + a] = v;
      } else {
        raw.xyz[3 * i + a] = ValueAt(point + axes[a]->offset, axes[a]->datatype);
      }
    }
    if (intensity != nullptr) {
      raw.intensity[i] =
          static_cast<float>(ValueAt(point + intensity->offset, intensity->datatype));
    }
    if (ring != nullptr) {
      const double r = ValueAt(point + ring->offset, ring->datatype);
      if (!(r >= 0 && r <= 65535)) {
        Fail(path, StrCat({"point ", std::to_string(i), ": ring value out of range 0..65535"}));
      }
      raw.ring[i] = static_cast<uint16_t>(r);
    }
  }
  return raw;
}

// x y z intensity (float) and ring (uint16) packed as PCL's byte blob.
pcl::PCLPointCloud2 ToBlob(const algorithms::PointCloud& cloud) {
  pcl::PCLPointCloud2 blob;
  blob.width = cloud.width;
  blob.height = cloud.height;
  blob.is_dense = false;
  auto add_field = [&blob](const char* name, uint8_t type, uint32_t size) {
    pcl::PCLPointField field;
    field.name = name;
    field.offset = blob.point_step;
    field.datatype = type;
    field.count = 1;
    blob.fields.push_back(field);
    blob.point_step += size;
  };
  add_field("x", pcl::PCLPointField::FLOAT32, 4);
  add_field("y", pcl::PCLPointField::FLOAT32, 4);
  add_field("z", pcl::PCLPointField::FLOAT32, 4);
  const bool has_intensity = !cloud.intensity.empty();
  const bool has_ring = !cloud.ring.empty();
  if (has_intensity) add_field("intensity", pcl::PCLPointField::FLOAT32, 4);
  if (has_ring) add_field("ring", pcl::PCLPointField::UINT16, 2);
  blob.row_step = blob.point_step * blob.width;
  blob.data.resize(static_cast<size_t>(blob.point_step) * cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i) {
    uint8_t* point = blob.data.data() + i * blob.point_step;
    std::memcpy(point, cloud.points[i].data(), 12);
    if (has_intensity) std::memcpy(point + 12, &cloud.intensity[i], 4);
    if (has_ring) std::memcpy(point + (has_intensity ? 16 : 12), &cloud.ring[i], 2);
  }
  return blob;
}

// One "x y z [intensity] [ring]" line per point, shortest round-trip decimals.
void AppendAsciiPoints(const algorithms::PointCloud& cloud, std::string* body) {
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      if (a > 0) *body += ' ';
      scan_io_internal::AppendNumber(body, cloud.points[i][a]);
    }
    if (!cloud.intensity.empty()) {
      *body += ' ';
      scan_io_internal::AppendNumber(body, cloud.intensity[i]);
    }
    if (!cloud.ring.empty()) body->append(" ").append(std::to_string(cloud.ring[i]));
    *body += '\n';
  }
}

}  // namespace

RawScan ReadPcd(const std::string& path) {
  const PcdHeader header = ReadHeader(path);
  CheckDataLength(header, path);
  pcl::PCLPointCloud2 cloud;
  Eigen::Vector4f viewpoint_origin;
  Eigen::Quaternionf viewpoint_orientation;
  int version = 0;
  SilencePcl();
  pcl::PCDReader reader;
  const int status = reader.read(path, cloud, viewpoint_origin, viewpoint_orientation, version, 0);
  if (status < 0) {
    Fail(path, StrCat({"PCL could not read the ", header.data,
                       " point data (malformed or truncated; for ascii: a line with a wrong "
                       "number of values, or fewer lines than POINTS)"}));
  }
  if (static_cast<uint64_t>(cloud.width) * cloud.height != header.points) {
    Fail(path, "point count mismatch between header and data");
  }
  RawScan raw = Convert(cloud, path);
  raw.stated_offset = header.offset;
  return raw;
}

void WritePcd(const std::string& path, const algorithms::PointCloud& cloud, PcdEncoding encoding) {
  const pcl::PCLPointCloud2 blob = ToBlob(cloud);
  pcl::PCDWriter writer;
  const Eigen::Vector4f viewpoint = Eigen::Vector4f::Zero();
  const Eigen::Quaternionf orientation = Eigen::Quaternionf::Identity();
  std::string body;
  if (encoding == PcdEncoding::kBinaryCompressed) {
    std::ostringstream out;
    if (writer.writeBinaryCompressed(out, blob, viewpoint, orientation) < 0) {
      Fail(path, "PCL could not compress the points");
    }
    body = std::move(out).str();
  } else if (encoding == PcdEncoding::kBinary) {
    body = writer.generateHeaderBinary(blob, viewpoint, orientation) + "DATA binary\n";
    body.append(reinterpret_cast<const char*>(blob.data.data()), blob.data.size());
  } else {
    body = writer.generateHeaderASCII(blob, viewpoint, orientation) + "DATA ascii\n";
    AppendAsciiPoints(cloud, &body);
  }
  // PCL's first line is a fixed comment; ours carries the origin. (Built by appending: GCC 12
  // raises a false -Wrestrict on string insert, see str_cat.h.)
  const size_t keep_from = body.rfind("#", 0) == 0 ? body.find('\n') : 0;
  std::string file =
      StrCat({"# .PCD v0.7 - ForestMap scan; ", scan_io_internal::OffsetComment(cloud.origin)});
  if (keep_from == 0) file += '\n';
  file.append(body, keep_from, std::string::npos);
  scan_io_internal::WriteFileBytes(path, file);
}

}  // namespace forestmap::client
