#pragma once

// Simulated drone views of tree maps, for tests, benchmarks and demos: ViewSimulator places a
// sensor in a map and reports what a LiDAR tree detector would: trees in range that no nearer
// trunk hides, with misses, false stems, position/DBH/axis noise and an optionally tilted sensor
// frame. Deterministic given the seeds; each call owns its generator. Frames and units as in
// algorithms/core/geometry.h (metres, radians, map z up). Maps to draw views of come from real
// stem maps or from forest_generator.h.

#include <cstdint>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/simulation/tree_grid.h"

namespace forestmap::algorithms {

struct ViewOptions {
  double range = 15.0;           // m, horizontal sensor range
  double miss_rate = 0.3;        // [0, 1], probability that a visible tree is not detected ...
  double far_miss_rate = -1;     // ... rising linearly to this at `range` ([0, 1]; < 0: constant)
  double false_rate = 0.2;       // >= 0, expected false stems per detected true tree (Poisson)
  double position_noise = 0.05;  // m, sd of the detected position per axis (x, y and z) ...
  double noise_per_metre = 0.0;  // ... plus this much (m) per metre of horizontal range
  double dbh_noise = 0.02;       // m, sd of the DBH error (detected DBH clamped to >= 0.01 m)
  double axis_noise = 0.035;     // rad, sd per axis of the stem-axis direction error (~2 deg)
  bool occlusion = true;         // a tree whose bearing lies in the angular shadow of a nearer
                                 // trunk (DBH, or 0.3 m when unknown) is not visible
  double max_tilt = 0.0;         // rad, <= 1.5: roll and pitch drawn uniformly in
                                 // [-max_tilt, max_tilt], kept when the total tilt <= max_tilt
  double sensor_height = 1.5;    // m, above the base height (z of the nearest tree, else 0)
  unsigned seed = 1;             // random seed
  void Check() const;            // throws std::invalid_argument
};

struct SimulatedView {
  Pose3 map_from_sensor = Pose3::Identity();  // truth; rotation Rz(yaw) Ry(pitch) Rx(roll)
  std::vector<DetectedTree> trees;            // sensor frame, shuffled
  std::vector<int64_t> truth_ids;             // map id of each detected tree; -1 = false stem
  int visible_trees = 0;                      // true trees in range and not occluded (pre-miss)
};

// Simulates sensor views of one map. Build once, query many times; Simulate is const and
// thread-safe.
class ViewSimulator {
 public:
  // Throws std::invalid_argument for a tree with a non-finite x or y.
  explicit ViewSimulator(std::vector<MapTree> map);

  // A view from the sensor at `position_xy` (m, map frame) looking along `yaw` (rad about map z).
  // Detections are map trees (+ noise) expressed in the sensor frame: position at the tree's z
  // (0 when unknown), DBH NaN when the map's is unknown, axis = map up in the sensor frame plus
  // noise. False stems are uniform in the range disc, >= 1 m from every map tree, with the DBH of
  // a random map tree plus noise. Throws std::invalid_argument for invalid options or pose.
  SimulatedView Simulate(const Eigen::Vector2d& position_xy, double yaw,
                         const ViewOptions& options) const;

  // Random poses (x m, y m, yaw rad) inside the map's bounding box, at least `margin` m from its
  // border, keeping only poses with >= `min_trees` trees within `range` m. Returns fewer than
  // `count` poses if 1000 * count draws do not find enough. Throws std::invalid_argument for a
  // negative count or margin, a non-positive range, or a margin that leaves no room.
  std::vector<Eigen::Vector3d> SamplePoses(int count, double margin, unsigned seed,
                                           int min_trees = 0, double range = 15.0) const;

  const std::vector<MapTree>& map() const { return map_; }
  const TreeGrid& grid() const { return grid_; }

 private:
  std::vector<int> VisibleTrees(const Eigen::Vector2d& position_xy, double range,
                                bool occlusion) const;

  std::vector<MapTree> map_;
  TreeGrid grid_;
};

// Convenience for one-off sampling: builds a ViewSimulator over `map` (a copy) and samples.
std::vector<Eigen::Vector3d> SamplePoses(const std::vector<MapTree>& map, int count, double margin,
                                         unsigned seed, int min_trees = 0, double range = 15.0);

}  // namespace forestmap::algorithms
