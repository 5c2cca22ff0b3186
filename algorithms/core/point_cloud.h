#pragma once
// A LiDAR scan as the detection pipeline sees it (axes and units: see geometry.h).
//
// Points are float, relative to `origin`: georeferenced clouds (UTM eastings of 500 km) would lose
// centimetres in float, so readers subtract a large offset once, in double, and keep it here.
// Organised scans (width x height, e.g. 2048 x 64) keep their NaN returns so that the beam and
// column of every point stay known; unorganised scans have height 1.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace forestmap::algorithms {

struct PointCloud {
  std::vector<Eigen::Vector3f> points;               // m, relative to `origin`; NaN = no return
  std::vector<float> intensity;                      // empty or one per point (sensor units)
  std::vector<uint16_t> ring;                        // empty or one per point: beam (laser) index
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // m; a point's full position = origin + p
  uint32_t width = 0;   // organised: columns; unorganised: points.size()
  uint32_t height = 1;  // organised: rows (beams); unorganised: 1

  size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  bool IsOrganised() const { return height > 1; }
};

// One revolution of a planar (2-D) LiDAR, in its own frame: beam i at angle angles[i] (rad,
// counter-clockwise from +x) measured ranges[i] (m; NaN or +inf = no return).
struct PlanarScan {
  std::vector<float> angles;
  std::vector<float> ranges;

  size_t size() const { return ranges.size(); }
};

}  // namespace forestmap::algorithms
