#pragma once
// PLY (Stanford polygon file) reading of the vertex element and binary writing, hand-written.
// Vertex properties used: x y z (float or double), intensity, ring; other elements are skipped.

#include <string>

#include "algorithms/core/point_cloud.h"
#include "client/io/scan_io_internal.h"

namespace forestmap::client {

scan_io_internal::RawScan ReadPly(const std::string& path);
void WritePly(const std::string& path, const algorithms::PointCloud& cloud);

}  // namespace forestmap::client
