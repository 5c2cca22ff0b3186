#pragma once
// Synthetic forests and simulated drone views of tree maps, for tests, benchmarks and demos.
//
// GenerateForest draws a stem map from a few spatial statistics: a hard-core (Matern/RSA style)
// background plus Thomas-process clusters (Thomas 1949; Illian et al. 2008, "Statistical Analysis
// and Modelling of Spatial Point Patterns", sec. 6.3.2), log-normal DBH and an optional smooth
// terrain. EstimateStemMapStatistics recovers those statistics from a real map (density, the 1st
// percentile of nearest-neighbour distances, and the cluster term from Ripley's K).
// ViewSimulator places a sensor in a map and reports what a LiDAR tree detector would: trees in
// range that no nearer trunk hides, with misses, false stems, position/DBH/axis noise and an
// optionally tilted sensor frame.
//
// Everything is deterministic given the seeds; each function owns its std::mt19937_64.
// Frames and units as in algorithms/geometry.h (metres, radians, map z up).

#include <cstdint>
#include <vector>

#include "algorithms/geometry.h"

namespace forestmap::algorithms {

// Spatial statistics of a stem map, enough to generate forests that look like a real one.
struct StemMapStatistics {
  double density = 0.05;        // trees per m^2
  double min_spacing = 0.5;     // m, hard-core distance: no two trees closer than this
  double cluster_fraction = 0;  // [0, 1], share of the trees placed in Thomas clusters
  double cluster_radius = 3;    // m, sd (per axis) of a clustered tree's offset from its centre
  double cluster_size = 6;      // trees, mean number of trees per cluster (>= 1)
  double dbh_log_mean = -1.6;   // ln(m), mean of ln(DBH); used when has_dbh
  double dbh_log_sd = 0.5;      // ln(m), sd of ln(DBH); used when has_dbh
  bool has_dbh = true;          // false: generated trees have unknown (NaN) DBH
  // Throws std::invalid_argument, naming the field, for values that cannot generate a forest
  // (including hard-core discs covering more than 40% of the area, which RSA cannot fill).
  void Check() const;
};

// Estimates the statistics of a real stem map. The window is the trees' bounding box, enlarged
// by the unbiased factor (n+1)/(n-1) per axis. min_spacing is the 1st percentile of the
// nearest-neighbour distances. The cluster term fits the excess neighbour count of Ripley's K
// (border-corrected), E(r) = A (1 - exp(-r^2 / 4 sigma^2)) for a Thomas process, giving
// cluster_radius = sigma and cluster_fraction * cluster_size = A (cluster_size stays at its
// default unless A exceeds it); below A = 0.5 the map counts as unclustered (cluster fields keep
// their defaults, cluster_fraction = 0). Maps larger than 20,000 trees use a regular subsample
// of focal trees. min_spacing is capped so that the result always passes Check(). has_dbh when
// at least half of the trees have a positive DBH.
// Throws std::invalid_argument with fewer than 10 trees, a non-finite x/y, or a degenerate extent.
StemMapStatistics EstimateStemMapStatistics(const std::vector<MapTree>& trees);

struct ForestOptions {
  double width = 100;      // m, map extent along x, from x = 0
  double height = 100;     // m, map extent along y, from y = 0
  double z_amplitude = 0;  // m, max |z| of a smooth terrain (3 plane waves, 50-200 m
                           // wavelength); 0 = flat, z = 0
  unsigned seed = 1;       // random seed
  void Check() const;      // throws std::invalid_argument
};

// Generates round(density * width * height) trees with ids 0..n-1 inside [0,width) x [0,height).
// Trees that find no room after many tries (very dense hard-core) are dropped, so n can be
// smaller. DBH is log-normal, clamped to [0.02, 2] m. Cluster offsets wrap around the area's
// edges so the intensity stays uniform. Uses a grid for the hard-core test: 1,000,000 trees take
// about 0.5-1 s. Throws std::invalid_argument for invalid statistics or options.
std::vector<MapTree> GenerateForest(const StemMapStatistics& stats, const ForestOptions& options);

struct ViewOptions {
  double range = 15.0;           // m, horizontal sensor range
  double miss_rate = 0.3;        // [0, 1], probability that a visible tree is not detected
  double false_rate = 0.2;       // >= 0, expected false stems per detected true tree (Poisson)
  double position_noise = 0.05;  // m, sd of the detected position per axis (x, y and z)
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

// A uniform 2-D grid over tree positions (compressed rows), for radius and nearest queries.
// Cells hold ~2 trees on average; memory is ~20 bytes per tree plus 4 per cell.
class TreeGrid {
 public:
  TreeGrid() = default;
  // Throws std::invalid_argument for a tree with a non-finite x or y (naming its id).
  explicit TreeGrid(const std::vector<MapTree>& trees);

  // Indices (into the constructor's vector) of trees within `radius` m horizontally of `center`.
  std::vector<int> InRadius(const Eigen::Vector2d& center, double radius) const;
  // Index of the horizontally nearest tree other than `exclude`, -1 when there is none.
  int Nearest(const Eigen::Vector2d& center, int exclude = -1) const;

  Eigen::Vector2d min_corner() const { return min_corner_; }  // m, bounding box of the trees
  Eigen::Vector2d max_corner() const { return max_corner_; }  // m

 private:
  int CellX(double x) const;
  int CellY(double y) const;

  std::vector<Eigen::Vector2d> xy_;  // tree positions, by cell (same order as index_)
  std::vector<int> index_;           // tree indices, by cell
  std::vector<int> cell_start_;      // cell c holds index_[cell_start_[c] .. cell_start_[c+1])
  Eigen::Vector2d min_corner_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d max_corner_ = Eigen::Vector2d::Zero();
  double cell_size_ = 1;  // m
  int nx_ = 0, ny_ = 0;
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
