#pragma once
// The thin client's job on board: one scan file -> the trees to send to the server, in the
// sensor frame (ReadScan, then algorithms::DetectTrunks with the given options).

#include <string>
#include <vector>

#include "algorithms/detection/trunk_detection.h"

namespace forestmap::client {

struct ScanTrees {
  std::vector<algorithms::DetectedTree> trees;  // sensor frame, best score first
  algorithms::TrunkDetectionStats stats;
};

// Throws ScanError (client/scan_io.h) for an unreadable scan, or for a georeferenced cloud (one
// read with an offset): a relocalization query must be in the sensor's own frame.
ScanTrees DetectScanTrees(const std::string& path,
                          const algorithms::TrunkDetectionOptions& options = {});

}  // namespace forestmap::client
