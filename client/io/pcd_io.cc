// The PCL adapter: the only file that includes PCL. PCL parses the point data (ascii, binary and
// LZF binary_compressed); the header is read and checked first (pcd_header.h), because PCL
// reports problems by printing them and returning -1, and we want errors that name the field and
// the place.

#include "client/io/pcd_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "client/io/pcd_header.h"
#include "client/io/str_cat.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::RawScan;

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
  const pcd_internal::PcdHeader header = pcd_internal::ReadHeader(path);
  pcd_internal::CheckDataLength(header, path);
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
