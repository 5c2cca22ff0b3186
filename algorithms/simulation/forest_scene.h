#pragma once
// A 3-D forest for the LiDAR scan simulator (algorithms/simulation/scan_simulation.h), built from a
// stem map.
//
// Map frame, z up, metres (geometry.h). The scene holds:
//  - terrain: a height field (cell_size grid, bilinear between nodes) sampled from a plane of
//    random direction and slope plus three plane waves of 10-40 m wavelength (undulation);
//  - one stem per map tree: a straight, slightly leaning, tapered cone from the terrain (its base
//    is where the stem axis meets the terrain) to the tree top. Its diameter is the tree's DBH at
//    1.3 m along the axis and changes by `taper` m per m of stem (wider below breast height).
//    The map's z is ignored: stems stand on the scene's terrain. Trees with unknown (or
//    non-positive) DBH get a log-normal DBH from the scene's RNG (SceneTree::dbh_drawn);
//  - a crown per tree (crown base to top): an ellipsoidal density volume a ray enters and is
//    stopped in with probability 1 - exp(-crown_density * path length);
//  - a few branches per tree below the crown: thin cylinders from the stem axis, pointing up;
//  - shrubs: small dense ellipsoidal volumes on the ground, uniform over the scene.
// Height allometry (a Chapman-Richards-like curve, per tree +-15%):
//   height = 1.3 + (max_height - 1.3) * (1 - exp(-5 * dbh)),  crown base = U(0.35, 0.65) height.
// Construction is deterministic given SceneOptions::seed (its own std::mt19937_64).
// Ray casting marches a 2-D grid (Amanatides & Woo 1987) along the ray's xy path and tests the
// terrain cell and the primitives listed in each cell; the first cell holding a hit ends it.
// The scene ends at the trees' bounding box plus `margin`: beyond it there is nothing (no
// terrain), so keep sensors at least their useful range inside, or raise the margin.

#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

// Point labels of a simulated scan: a scene tree index (>= 0) for stem returns, or one of these.
inline constexpr int32_t kLabelNoReturn = -1;  // NaN point
inline constexpr int32_t kLabelGround = -2;
inline constexpr int32_t kLabelShrub = -3;
inline constexpr int32_t kLabelCrown = -4;
inline constexpr int32_t kLabelBranch = -5;
inline constexpr int32_t kLabelBody = -6;   // the drone's own body (sensor frame, < 0.5 m)
inline constexpr int32_t kLabelMixed = -7;  // mixed pixel: range between a stem edge and behind

inline constexpr double kBreastHeight = 1.3;  // m along the stem axis from the ground

struct SceneOptions {
  uint64_t seed = 1;        // random seed of everything drawn for the scene
  double margin = 30;       // m, terrain and shrubs reach this far beyond the trees' bounding box
  double cell_size = 2.0;   // m, height field and ray-casting grid resolution, in [0.25, 10]
  double max_slope = 0.1;   // m/m, the terrain plane's gradient is uniform in [0, max_slope]
  double undulation = 0.4;  // m, amplitude of the terrain waves (sum of 3, |sum| <= this)
  double max_lean = 4 * M_PI / 180;  // rad, stem lean from vertical is uniform in [0, max_lean]
  double taper = 0.01;               // m of diameter per m of stem length, per tree x U(0.6, 1.4)
  double dbh_log_mean = -1.6;        // ln(m), DBH drawn for trees with unknown DBH (median 0.2 m)
  double dbh_log_sd = 0.4;           // ln(m); drawn DBH clamped to [0.05, 1.2] m
  double max_height = 30;            // m, asymptote of the height allometry (> 1.3)
  bool crowns = true;
  double crown_density = 0.6;  // 1/m, extinction coefficient inside a crown
  bool branches = true;
  int max_branches = 4;            // per tree, uniform in [0, max_branches]
  double branch_min_height = 2.0;  // m along the stem; branches start above this
  bool shrubs = true;
  double shrub_density = 0.01;    // shrubs per m^2 of scene area
  double shrub_extinction = 4.0;  // 1/m inside a shrub
  void Check() const;             // throws std::invalid_argument naming the field
};

// One stem of the scene, map frame.
struct SceneTree {
  int64_t id = 0;                                   // the map tree's id
  Eigen::Vector3d base = Eigen::Vector3d::Zero();   // m, stem axis meets the terrain
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit stem direction (leaning)
  double dbh = 0.2;                                 // m, at kBreastHeight along the axis
  bool dbh_drawn = false;   // true: the map had no DBH; drawn from the scene's RNG
  double taper = 0.01;      // m of diameter per m of stem
  double height = 15;       // m along the axis, top of the stem cone
  double crown_base = 8;    // m along the axis (crown from here to height)
  double crown_radius = 2;  // m, horizontal semi-axis of the crown ellipsoid

  // Stem radius (m) at `s` m along the axis; >= 5 mm.
  double RadiusAt(double s) const {
    const double r = 0.5 * dbh + 0.5 * taper * (kBreastHeight - s);
    return r > 0.005 ? r : 0.005;
  }
  Eigen::Vector3d PointAt(double s) const { return base + s * axis; }
};

// A shape the rays can hit (map frame).
struct ScenePrimitive {
  enum class Kind : uint8_t {
    kCone,      // a stem: radius(s) = radius + radius_slope * s, s in [0, length] from `origin`
    kCylinder,  // a branch: constant radius, s in [0, length]
    kVolume,    // a crown or shrub: axis-aligned ellipsoid (centre `origin`, semi-axes `size`)
  };
  Kind kind = Kind::kCone;
  int32_t label = kLabelGround;                      // tree index (stems) or kLabel*
  int32_t tree = -1;                                 // owning tree index, -1 for shrubs
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // m
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();   // unit (cone, cylinder)
  Eigen::Vector3d size = Eigen::Vector3d::Zero();    // m, semi-axes (volume)
  double length = 0;                                 // m (cone, cylinder)
  double radius = 0;                                 // m at s = 0 (cone, cylinder)
  double radius_slope = 0;                           // m of radius per m along the axis (cone)
  double extinction = 0;                             // 1/m (volume)
};

// The nearest hit of one ray.
struct RayHit {
  double range = std::numeric_limits<double>::infinity();  // m along the ray; inf = nothing
  int32_t label = kLabelNoReturn;
  int32_t primitive = -1;  // index into ForestScene::primitives(), -1 for terrain / nothing
  bool partial = false;    // the beam footprint only partly covered the object (a stem edge)
  // The nearest stem edge the footprint touched without returning (for mixed pixels): its range
  // (m, inf = none), the stem's primitive and the covered share of the footprint in [0, 1].
  double edge_range = std::numeric_limits<double>::infinity();
  int32_t edge_primitive = -1;
  double edge_fraction = 0;
  bool hit() const { return primitive >= 0 || label != kLabelNoReturn; }
};

// Beam of one ray: origin and unit direction in the map frame, plus what decides partial and
// volume hits. Equal keys give equal stochastic decisions, so results are reproducible.
struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();      // m
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit
  double max_range = 100;                                // m
  double footprint_per_m = 0;  // m of footprint radius per m of range (divergence / 2)
  uint64_t key = 0;            // seeds this ray's random draws
};

class ForestScene {
 public:
  // Throws std::invalid_argument for invalid options or a tree with a non-finite x or y (naming
  // its id). An empty map gives terrain and shrubs over [-margin, margin]^2.
  ForestScene(const std::vector<MapTree>& trees, const SceneOptions& options);

  const std::vector<SceneTree>& trees() const { return trees_; }
  const std::vector<ScenePrimitive>& primitives() const { return primitives_; }
  const SceneOptions& options() const { return options_; }
  Eigen::Vector2d min_corner() const { return min_corner_; }  // m, extent of the scene
  Eigen::Vector2d max_corner() const { return max_corner_; }

  // m, terrain height at (x, y): bilinear in the height field, clamped at the scene's edge.
  double TerrainHeight(double x, double y) const;

  // Nearest hit along the ray within (0, max_range]. Thread-safe.
  RayHit CastRay(const Ray& ray) const;
  // The same by testing every primitive and terrain cell (slow; the reference for tests).
  RayHit CastRayBruteForce(const Ray& ray) const;

 private:
  void BuildTerrain(std::mt19937_64& rng);
  void BuildTree(const MapTree& tree, std::mt19937_64& rng);
  void BuildBranches(const SceneTree& tree, int index, std::mt19937_64& rng);
  void BuildShrubs(std::mt19937_64& rng);
  void BuildGrid();
  double NodeHeight(int ix, int iy) const { return heights_[iy * (nx_ + 1) + ix]; }
  // Terrain hit in cell (cx, cy) for t in [t0, t1], or inf.
  double TerrainHitInCell(const Ray& ray, int cx, int cy, double t0, double t1) const;
  void TestPrimitive(const Ray& ray, int index, RayHit* best) const;

  SceneOptions options_;
  std::vector<SceneTree> trees_;
  std::vector<ScenePrimitive> primitives_;
  Eigen::Vector2d min_corner_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d max_corner_ = Eigen::Vector2d::Zero();
  int nx_ = 0, ny_ = 0;                       // cells; the height field has (nx_+1) x (ny_+1) nodes
  std::vector<double> heights_;               // m, node heights, row-major (y rows)
  std::vector<float> cell_top_;               // m, max z of terrain and primitives per cell
  float scene_top_ = 0;                       // m, max of cell_top_
  std::vector<Eigen::Vector2f> primitive_z_;  // m, (min, max) z of each primitive, padded
  std::vector<int> cell_start_;  // primitives of cell c: cell_items_[start[c] .. start[c+1])
  std::vector<int> cell_items_;
};

}  // namespace forestmap::algorithms
