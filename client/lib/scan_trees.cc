#include "client/lib/scan_trees.h"

#include <sstream>

#include "client/io/scan_io.h"

namespace forestmap::client {

ScanTrees DetectScanTrees(const std::string& path,
                          const algorithms::TrunkDetectionOptions& options) {
  const algorithms::PointCloud cloud = ReadScan(path);
  if (cloud.origin.squaredNorm() > 0) {
    std::ostringstream message;
    message << path << ": a georeferenced cloud (offset " << cloud.origin.transpose()
            << " m); a relocalization needs a scan in the sensor's own frame";
    throw ScanError(message.str());
  }
  const algorithms::TrunkDetectionResult result = algorithms::DetectTrunks(cloud, options);
  ScanTrees out;
  out.stats = result.stats;
  out.trees.reserve(result.trees.size());
  for (const algorithms::DetectedTrunk& trunk : result.trees) out.trees.push_back(trunk.tree);
  return out;
}

ScanDetection DetectTrunksInScan(const std::string& path, algorithms::TrunkDetectionOptions options,
                                 bool multi_view) {
  const algorithms::PointCloud cloud = ReadScan(path);
  if (multi_view || cloud.origin.squaredNorm() > 0) {
    options.filter.self_radius = 0;
    options.stem.sensor_at_origin = false;
  }
  options.Check();
  return {algorithms::DetectTrunks(cloud, options), cloud.origin};
}

}  // namespace forestmap::client
