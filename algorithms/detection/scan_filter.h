#pragma once
// First detection stage: the valid returns of a scan, without the drone's own body.
//
// A drone-borne LiDAR sees its own arms and landing gear, and many drivers report "no return" as
// a point at the sensor origin; both sit inside a small sphere around the origin (Zmeškalová 2023,
// sec. 2.2: duplicates at the origin first, then every point with |p| <= threshold, 0.35 m there).

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "algorithms/core/point_cloud.h"

namespace forestmap::algorithms {

struct ScanFilterOptions {
  double self_radius = 0.5;  // m, returns closer to the sensor origin are the drone itself
  double max_range = 0;      // m, horizontal range limit from the origin; 0 = none
  void Check() const;
};

struct ScanFilterResult {
  std::vector<Eigen::Vector3f> points;  // kept points, m, same frame as the cloud's points
  std::vector<uint32_t> source_index;   // index of each kept point in the input cloud
  size_t invalid = 0;                   // NaN / infinite returns
  size_t origin_duplicates = 0;         // points at the origin itself (within 1 mm)
  size_t self_returns = 0;              // other points inside self_radius
  size_t out_of_range = 0;              // beyond max_range
};

ScanFilterResult FilterScan(const PointCloud& cloud, const ScanFilterOptions& options);

}  // namespace forestmap::algorithms
