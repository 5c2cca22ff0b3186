#pragma once
// Text point clouds (.csv .xyz .txt: x y z [intensity]) and planar scans (angle_rad,range_m).

#include <string>

#include "algorithms/core/point_cloud.h"
#include "client/io/scan_io_internal.h"

namespace forestmap::client {

scan_io_internal::RawScan ReadTextScan(const std::string& path);
void WriteCsvScan(const std::string& path, const algorithms::PointCloud& cloud);

algorithms::PlanarScan ReadPlanarCsv(const std::string& path);
void WritePlanarCsv(const std::string& path, const algorithms::PlanarScan& scan);

}  // namespace forestmap::client
