#pragma once
// A LiDAR scan simulator with exact truth, for testing trunk detection (Zmeškalová 2023, ch. 2-5)
// against known stems. A scanner (scanner_model.h) placed at `map_from_sensor` in a ForestScene
// (forest_scene.h) casts every beam x column; each beam returns its nearest hit plus Gaussian
// range noise, or NaN.
//
// Beam divergence: a beam's footprint has radius w = range * divergence / 2. A beam whose centre
// line passes the stem axis at distance d hits the stem surface itself when d < r (the stem
// radius there). For r <= d < r + w only the footprint's edge touches the stem: it returns from
// the stem with probability (r + w - d) / w (0 when just touching, 1 when half the footprint is
// on the stem), at the range of the nearest covered part of the stem, placed on the beam's centre
// line, i.e. up to w outside the true surface. Points near stem edges are so pushed outwards and
// circle fits overestimate DBH by a few millimetres to centimetres, as real scans do. Branches
// (thin cylinders) return when the footprint covers half of their width.
// With `mixed_pixels`, an edge beam that touches a stem but does not return from it reports a
// range between the stem and what lies behind (the "mixed pixel" of phase/first-return sensors),
// weighted by the covered share of the footprint, labelled kLabelMixed.
//
// Output (sensor frame, organised: width = columns, height = rings, points[ring * width +
// column], NaN = no return, ring = beam index with ring 0 the highest beam), one label per point
// (forest_scene.h: tree index >= 0 for stem returns, kLabelGround, kLabelShrub, kLabelCrown,
// kLabelBranch, kLabelBody, kLabelMixed, kLabelNoReturn), and truth for every scene tree.
//
// Truth (SimulatedTreeTruth): `position` is where the stem axis meets the ground, `dbh` at 1.3 m
// along the stem, `axis` the unit stem direction, all in the sensor frame (the frames of
// trunk_detection.h). `range` is the horizontal (map frame) distance from the sensor to the stem
// axis at breast height. `stem_points` counts the returns labelled with the tree, `breast_points`
// those between 0.5 and 3 m along the stem. A tree is `visible` when breast_points >=
// kMinVisibleStemPoints (10) and range <= the scanner's max range: enough of the stem near breast
// height was seen for a circle/cylinder fit. (Planar scans: >= kMinVisiblePlanarPoints (3) returns
// on the stem.)
//
// Every random draw comes from a hash of (seed, beam): equal seeds give identical scans, and the
// result does not depend on the number of threads.

#include <cstdint>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/point_cloud.h"
#include "algorithms/simulation/forest_scene.h"
#include "algorithms/simulation/scanner_model.h"

namespace forestmap::algorithms {

inline constexpr int kMinVisibleStemPoints = 10;   // stem returns 0.5-3 m along the stem
inline constexpr int kMinVisiblePlanarPoints = 3;  // stem returns of a planar scan
inline constexpr double kVisibleStemLow = 0.5;     // m along the stem
inline constexpr double kVisibleStemHigh = 3.0;    // m along the stem

struct ScanNoiseOptions {
  bool range_noise = true;      // Gaussian range noise with the scanner's range_noise_sd
  bool beam_divergence = true;  // footprint model (partial stem-edge returns); false = thin rays
  bool mixed_pixels = false;    // edge misses report a range between stem and background
  double dropout = 0.0;         // [0, 1), probability that a beam with a hit returns nothing
  bool drone_body = true;       // the drone's arms and landing legs (sensor frame, 0.25-0.5 m)
  int threads = 1;              // >= 1, worker threads (results do not depend on it)
  void Check() const;           // throws std::invalid_argument naming the field
};

struct SimulatedTreeTruth {
  int index = 0;                                       // index into ForestScene::trees()
  int64_t id = 0;                                      // map tree id
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m, stem axis meets ground, sensor frame
  double dbh = 0;                                      // m, at 1.3 m along the stem
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();     // unit stem direction, sensor frame
  double range = 0;       // m, horizontal distance sensor -> stem axis at breast height
  int stem_points = 0;    // returns labelled with this tree
  int breast_points = 0;  // of these, between kVisibleStemLow and kVisibleStemHigh
  bool visible = false;   // see the header comment
};

struct ScanSimulationResult {
  PointCloud cloud;                       // sensor frame (origin zero), organised
  std::vector<int32_t> labels;            // one per point
  std::vector<SimulatedTreeTruth> trees;  // one per scene tree, in scene order
  Pose3 map_from_sensor = Pose3::Identity();
  int returns = 0;  // finite points
};

// Throws std::invalid_argument for an invalid scanner, options or a non-finite pose.
ScanSimulationResult SimulateScan(const ForestScene& scene, const Pose3& map_from_sensor,
                                  const ScannerModel& scanner, const ScanNoiseOptions& noise,
                                  uint32_t seed);

// A planar (2-D) scan: the scanner's beams lie in the sensor's x-y plane.
struct PlanarTreeTruth {
  int index = 0;                                     // index into ForestScene::trees()
  int64_t id = 0;                                    // map tree id
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // m, stem axis meets the scan plane
  double diameter = 0;   // m, stem diameter where the axis meets the scan plane
  double height = 0;     // m along the stem of that point (1.3 = breast height)
  double range = 0;      // m, |center|
  int points = 0;        // returns on this stem
  bool visible = false;  // points >= kMinVisiblePlanarPoints and range <= max range
};

struct PlanarScanSimulationResult {
  PlanarScan scan;                     // angles = the scanner's azimuths, NaN = no return
  std::vector<int32_t> labels;         // one per beam
  std::vector<PlanarTreeTruth> trees;  // scene trees whose stem crosses the scan plane
  Pose3 map_from_sensor = Pose3::Identity();
};

// `scanner` must be planar (one ring; e.g. PlanarScanner()). Throws std::invalid_argument.
PlanarScanSimulationResult SimulatePlanarScan(const ForestScene& scene,
                                              const Pose3& map_from_sensor,
                                              const ScannerModel& scanner,
                                              const ScanNoiseOptions& noise, uint32_t seed);

// The pose of a drone hovering `height_above_ground` m over the terrain at (x, y), with yaw,
// pitch and roll (rad; rotation Rz(yaw) Ry(pitch) Rx(roll), as in simulation.h).
Pose3 DronePose(const ForestScene& scene, double x, double y, double height_above_ground,
                double yaw, double pitch = 0, double roll = 0);

}  // namespace forestmap::algorithms
