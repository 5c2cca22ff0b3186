#include "client/io/scan_io.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include "client/io/las_io.h"
#include "client/io/pcd_io.h"
#include "client/io/ply_io.h"
#include "client/io/scan_io_internal.h"
#include "client/io/str_cat.h"
#include "client/io/text_scan_io.h"

namespace forestmap::client {
namespace {

using scan_io_internal::Fail;
using scan_io_internal::RawScan;

std::string LowerExtension(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// origin = floor(min bound) over the finite points (the rule of the shared data's converters).
Eigen::Vector3d FloorMinBound(const std::vector<double>& xyz) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (size_t i = 0; i + 2 < xyz.size(); i += 3) {
    if (!std::isfinite(xyz[i]) || !std::isfinite(xyz[i + 1]) || !std::isfinite(xyz[i + 2])) {
      continue;
    }
    lo = lo.cwiseMin(Eigen::Vector3d(xyz[i], xyz[i + 1], xyz[i + 2]));
  }
  if (!lo.allFinite()) return Eigen::Vector3d::Zero();
  return lo.array().floor().matrix();
}

bool HasLargeCoordinate(const std::vector<double>& xyz, double limit) {
  for (double v : xyz) {
    if (std::isfinite(v) && std::abs(v) > limit) return true;
  }
  return false;
}

}  // namespace

void ScanReadOptions::Check() const {
  if (!(large_coordinate_m > 0.0) || !std::isfinite(large_coordinate_m)) {
    throw std::invalid_argument("ScanReadOptions: large_coordinate_m must be positive and finite");
  }
}

void ScanWriteOptions::Check() const {
  if (pcd_encoding != PcdEncoding::kBinary && pcd_encoding != PcdEncoding::kAscii &&
      pcd_encoding != PcdEncoding::kBinaryCompressed) {
    throw std::invalid_argument("ScanWriteOptions: unknown pcd_encoding");
  }
}

namespace scan_io_internal {

algorithms::PointCloud FinishScan(RawScan raw, const ScanReadOptions& options,
                                  const std::string& path) {
  const size_t n = raw.size();
  if (static_cast<uint64_t>(raw.width) * raw.height != n) {
    Fail(path, StrCat({"width x height = ", std::to_string(raw.width), " x ",
                       std::to_string(raw.height), " but ", std::to_string(n), " points"}));
  }
  if (!raw.intensity.empty() && raw.intensity.size() != n) Fail(path, "intensity count mismatch");
  if (!raw.ring.empty() && raw.ring.size() != n) Fail(path, "ring count mismatch");

  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  if (HasLargeCoordinate(raw.xyz, options.large_coordinate_m)) shift = FloorMinBound(raw.xyz);

  algorithms::PointCloud cloud;
  cloud.origin = raw.stated_offset + shift;
  const bool organised = raw.height > 1;
  const bool keep_all = organised || options.keep_invalid_points;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.points.reserve(n);
  if (!raw.intensity.empty()) cloud.intensity.reserve(n);
  if (!raw.ring.empty()) cloud.ring.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    const double* p = &raw.xyz[3 * i];
    const bool finite = std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
    if (!finite && !keep_all) continue;
    if (finite) {
      cloud.points.emplace_back(static_cast<float>(p[0] - shift.x()),
                                static_cast<float>(p[1] - shift.y()),
                                static_cast<float>(p[2] - shift.z()));
    } else {
      cloud.points.emplace_back(nan, nan, nan);
    }
    if (!raw.intensity.empty()) cloud.intensity.push_back(raw.intensity[i]);
    if (!raw.ring.empty()) cloud.ring.push_back(raw.ring[i]);
  }
  cloud.height = organised ? raw.height : 1;
  cloud.width = organised ? raw.width : static_cast<uint32_t>(cloud.points.size());
  return cloud;
}

bool ParseOffsetComment(std::string_view line, const std::string& where, Eigen::Vector3d* offset) {
  static constexpr std::string_view kPhrase = "offset subtracted:";
  const size_t at = line.find(kPhrase);
  if (at == std::string_view::npos) return false;
  std::string rest(line.substr(at + kPhrase.size()));
  std::istringstream in(rest);
  double x = 0, y = 0, z = 0;
  if (!(in >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
    Fail(where, StrCat({"header comment 'offset subtracted:' needs three finite numbers, got '",
                        rest, "'"}));
  }
  *offset = Eigen::Vector3d(x, y, z);
  return true;
}

std::string OffsetComment(const Eigen::Vector3d& origin) {
  std::string out = "offset subtracted:";
  for (int i = 0; i < 3; ++i) {
    out += ' ';
    AppendNumber(&out, origin[i]);
  }
  return out;
}

std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) Fail(path, "cannot open file for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  std::string bytes = std::move(buffer).str();
  if (in.bad()) Fail(path, "read error");
  if (bytes.empty()) Fail(path, "empty file");
  return bytes;
}

void WriteFileBytes(const std::string& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) Fail(path, "cannot open file for writing");
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) Fail(path, "write failed");
}

void Fail(const std::string& where, const std::string& problem) {
  throw ScanError(StrCat({where, ": ", problem}));
}

void CheckCloudForWriting(const algorithms::PointCloud& cloud, const std::string& path) {
  const size_t n = cloud.size();
  if (static_cast<uint64_t>(cloud.width) * cloud.height != n) {
    Fail(path, StrCat({"cannot write: width x height = ", std::to_string(cloud.width), " x ",
                       std::to_string(cloud.height), " but the cloud has ", std::to_string(n),
                       " points"}));
  }
  if (!cloud.intensity.empty() && cloud.intensity.size() != n) {
    Fail(path, "cannot write: intensity has a different size than points");
  }
  if (!cloud.ring.empty() && cloud.ring.size() != n) {
    Fail(path, "cannot write: ring has a different size than points");
  }
  if (!cloud.origin.allFinite()) Fail(path, "cannot write: origin is not finite");
}

template <typename T>
static void AppendNumberImpl(std::string* out, T value) {
  if (std::isnan(value)) {
    out->append("nan");
    return;
  }
  if (std::isinf(value)) {
    out->append(value > 0 ? "inf" : "-inf");
    return;
  }
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out->append(buffer, result.ptr);
}

void AppendNumber(std::string* out, double value) { AppendNumberImpl(out, value); }
void AppendNumber(std::string* out, float value) { AppendNumberImpl(out, value); }

}  // namespace scan_io_internal

algorithms::PointCloud ReadScan(const std::string& path, const ScanReadOptions& options) {
  options.Check();
  const std::string ext = LowerExtension(path);
  RawScan raw;
  if (ext == ".pcd") {
    raw = ReadPcd(path);
  } else if (ext == ".ply") {
    raw = ReadPly(path);
  } else if (ext == ".las") {
    raw = ReadLas(path);
  } else if (ext == ".laz") {
    Fail(path, StrCat({"LAZ is compressed: decompress first (e.g. laszip -i ", path, " -o ",
                       path.substr(0, path.size() - 4), ".las)"}));
  } else if (ext == ".csv" || ext == ".xyz" || ext == ".txt") {
    raw = ReadTextScan(path);
  } else {
    Fail(path, StrCat({"unknown scan file extension '", ext,
                       "' (expected .pcd, .ply, .las, .csv, .xyz or .txt)"}));
  }
  return scan_io_internal::FinishScan(std::move(raw), options, path);
}

void WriteScan(const std::string& path, const algorithms::PointCloud& cloud,
               const ScanWriteOptions& options) {
  options.Check();
  scan_io_internal::CheckCloudForWriting(cloud, path);
  const std::string ext = LowerExtension(path);
  if (ext == ".pcd") {
    WritePcd(path, cloud, options.pcd_encoding);
  } else if (ext == ".ply") {
    WritePly(path, cloud);
  } else if (ext == ".csv") {
    WriteCsvScan(path, cloud);
  } else {
    Fail(path, StrCat({"cannot write scans as '", ext, "' (expected .pcd, .ply or .csv)"}));
  }
}

algorithms::PlanarScan ReadPlanarScan(const std::string& path) { return ReadPlanarCsv(path); }

void WritePlanarScan(const std::string& path, const algorithms::PlanarScan& scan) {
  WritePlanarCsv(path, scan);
}

}  // namespace forestmap::client
