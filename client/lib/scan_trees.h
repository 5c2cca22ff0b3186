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

// Throws ScanError (client/io/scan_io.h) for an unreadable scan, or for a georeferenced cloud (one
// read with an offset): a relocalization query must be in the sensor's own frame.
ScanTrees DetectScanTrees(const std::string& path,
                          const algorithms::TrunkDetectionOptions& options = {});

// The trunks of any scan, as `forestmap detect` finds them: a georeferenced (offset) or merged
// (`multi_view`) cloud has no sensor at its origin, so the drone-body filter and the
// sensor-facing arc checks are off for it.
struct ScanDetection {
  algorithms::TrunkDetectionResult result;           // positions in the cloud's frame
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // m: add to positions for the file's frame
};

// Throws ScanError for an unreadable scan and std::invalid_argument for bad `options`.
ScanDetection DetectTrunksInScan(const std::string& path, algorithms::TrunkDetectionOptions options,
                                 bool multi_view);

}  // namespace forestmap::client
