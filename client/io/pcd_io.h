#pragma once
// PCD files through PCL (the only place PCL is used; its headers stay inside pcd_io.cc).

#include <string>

#include "algorithms/core/point_cloud.h"
#include "client/io/scan_io.h"
#include "client/io/scan_io_internal.h"

namespace forestmap::client {

scan_io_internal::RawScan ReadPcd(const std::string& path);
void WritePcd(const std::string& path, const algorithms::PointCloud& cloud, PcdEncoding encoding);

}  // namespace forestmap::client
