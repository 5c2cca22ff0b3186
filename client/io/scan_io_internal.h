#pragma once
// Shared by the format readers and writers of scan_io (not for other users): the raw cloud a
// reader produces before the origin is chosen, and the error helpers.

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "algorithms/core/point_cloud.h"
#include "client/io/scan_io.h"

namespace forestmap::client::scan_io_internal {

// Coordinates as stored in the file, in double, plus what the header says about them.
struct RawScan {
  std::vector<double> xyz;       // 3 per point, m, relative to stated_offset
  std::vector<float> intensity;  // empty or one per point
  std::vector<uint16_t> ring;    // empty or one per point
  uint32_t width = 0;            // organised columns, or point count
  uint32_t height = 1;           // organised rows, or 1
  Eigen::Vector3d stated_offset = Eigen::Vector3d::Zero();  // m, from a header comment

  size_t size() const { return xyz.size() / 3; }
};

// Chooses the origin (stated offset, plus floor(min bound) for large coordinates), converts to
// float relative to it, and drops or keeps non-finite points. `path` names the file in errors.
algorithms::PointCloud FinishScan(RawScan raw, const ScanReadOptions& options,
                                  const std::string& path);

// Parses "... offset subtracted: X Y Z" anywhere in a comment line; false if absent.
// Throws ScanError (via `where`) when the phrase is present but the numbers are not.
bool ParseOffsetComment(std::string_view line, const std::string& where, Eigen::Vector3d* offset);

// The comment WriteScan puts in headers: "offset subtracted: X Y Z" with 0.1 mm precision...
// written with full double precision so that a round trip restores the origin exactly.
std::string OffsetComment(const Eigen::Vector3d& origin);

// Whole file as bytes. Throws ScanError "FILE: cannot open ..." / "FILE: empty file".
std::string ReadFileBytes(const std::string& path);

// Writes bytes to a file, throwing ScanError naming it on failure.
void WriteFileBytes(const std::string& path, std::string_view bytes);

[[noreturn]] void Fail(const std::string& where, const std::string& problem);

// Little-endian read of a T at `offset` of `bytes` (the LAS readers); callers check bounds first.
template <typename T>
T Get(const std::string& bytes, size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

constexpr size_t kVlrHeaderSize = 54;  // bytes of a LAS variable-length record's header

// Checks that the per-point arrays and width x height agree with points.size().
void CheckCloudForWriting(const algorithms::PointCloud& cloud, const std::string& path);

// Shortest round-trip text of a number ("nan", "inf" for non-finite values).
void AppendNumber(std::string* out, double value);
void AppendNumber(std::string* out, float value);

}  // namespace forestmap::client::scan_io_internal
