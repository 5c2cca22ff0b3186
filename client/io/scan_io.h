#pragma once
// Reading and writing LiDAR scans (3-D point clouds and planar 2-D scans) in the common formats.
//
// Formats, chosen by the file extension (case-insensitive):
//   .pcd            read (via PCL): ascii, binary, binary_compressed; fields x y z (F 4 or F 8),
//                   optional intensity and ring (any numeric type). Write: binary (default),
//                   ascii or binary_compressed with x y z intensity (F 4) and ring (U 2).
//   .ply            read: ascii, binary_little_endian, binary_big_endian; vertex x y z (any
//                   scalar type, float or double), optional intensity / scalar_intensity and
//                   ring / scalar_ring; other elements (faces, ...) are skipped. Write: binary LE.
//   .las            read: LAS 1.0-1.4 uncompressed, point data formats 0-10 (as allowed by the
//                   version), extra bytes honoured; intensity always, ring from an extra-bytes
//                   attribute named "ring" (any case). Not written.
//   .laz            rejected: "LAZ is compressed: decompress first (e.g. laszip -i X.laz -o X.las)"
//   .csv .xyz .txt  read: one point per line, comma or space/tab separated, '#' comments, blank
//                   lines. With a header line, columns are found by name (x y z, optional
//                   intensity|i|scalar_intensity, ring; "//X" of CloudCompare works); without,
//                   they are x y z [intensity] by position. Write (.csv): x,y,z[,intensity][,ring].
//
// Header comments understood on reading, and written by WriteScan (PCD '#' line, PLY
// "comment", CSV '#' line):
//   "... offset subtracted: X Y Z"  the file's coordinates are relative to (X, Y, Z) m; this is
//                                   what the shared data's converters write, e.g. spanner_ponderosa
//                                   "offset subtracted: 470627.000 3810222.000 2278.000". It
//                                   becomes PointCloud::origin.
//   "organised: W H"                (PLY and CSV only; PCD has WIDTH/HEIGHT) width x height.
//
// Georeferenced clouds keep full precision: PointCloud points are float relative to a double
// `origin` (see algorithms/core/point_cloud.h). Readers take coordinates in double (LAS:
// X * scale + offset); when any finite coordinate exceeds ScanReadOptions::large_coordinate_m
// (10 km), origin += floor(min bound over the points) is subtracted in double before the points
// become float. Small-coordinate clouds (sensor frames) keep origin = stated offset (usually 0).
//
// Organised clouds (height > 1) keep their NaN returns (inf becomes NaN too) so that width x
// height stays valid; unorganised clouds drop non-finite points unless
// ScanReadOptions::keep_invalid_points.
//
// Every failure throws ScanError whose message names the file and the place:
// "FILE: problem", "FILE:LINE: problem" (text formats and headers) or "FILE: byte N: problem".

#include <cstdint>
#include <stdexcept>
#include <string>

#include "algorithms/core/point_cloud.h"

namespace forestmap::client {

class ScanError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ScanReadOptions {
  // Unorganised clouds: keep NaN/inf points (stored as NaN) instead of dropping them. Organised
  // clouds always keep them.
  bool keep_invalid_points = false;
  // m; when any finite coordinate's magnitude exceeds this, origin = floor(min bound) is
  // subtracted in double before the points become float (float steps are 0.25 m at 3.8e6 m).
  double large_coordinate_m = 10000.0;

  void Check() const;  // throws std::invalid_argument
};

enum class PcdEncoding { kBinary, kAscii, kBinaryCompressed };

struct ScanWriteOptions {
  PcdEncoding pcd_encoding = PcdEncoding::kBinary;  // .pcd only

  void Check() const;  // throws std::invalid_argument
};

// Reads a 3-D scan; the format comes from the extension. Throws ScanError.
algorithms::PointCloud ReadScan(const std::string& path, const ScanReadOptions& options = {});

// Writes a 3-D scan (.pcd, .ply or .csv) keeping width/height (organised clouds with NaNs),
// intensity, ring and origin (as an "offset subtracted: X Y Z" header comment). Throws ScanError
// for an unsupported extension, an inconsistent cloud or a failed write.
void WriteScan(const std::string& path, const algorithms::PointCloud& cloud,
               const ScanWriteOptions& options = {});

// Planar scans: CSV with columns angle_rad,range_m (header line optional, '#' comments allowed).
// Ranges may be nan/inf (no return); angles must be finite. Throws ScanError "FILE:LINE: ...".
algorithms::PlanarScan ReadPlanarScan(const std::string& path);
void WritePlanarScan(const std::string& path, const algorithms::PlanarScan& scan);

}  // namespace forestmap::client
