#include "algorithms/simulation/forest_scene.h"

#include <algorithm>
#include <array>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "algorithms/core/check.h"
#include "algorithms/core/random.h"
#include "algorithms/simulation/tree_grid.h"

namespace forestmap::algorithms {
namespace {

constexpr double kBoundsPad = 0.25;  // m, grid registration pad for the beam footprint

// Axis-aligned bounding box (min, max corners, m) of a primitive.
std::pair<Eigen::Vector3d, Eigen::Vector3d> PrimitiveBounds(const ScenePrimitive& p) {
  if (p.kind == ScenePrimitive::Kind::kVolume) return {p.origin - p.size, p.origin + p.size};
  const Eigen::Vector3d end = p.origin + p.length * p.axis;
  // A cone's widest end is its base (radius_slope <= 0).
  const Eigen::Vector3d r = Eigen::Vector3d::Constant(p.radius);
  return {p.origin.cwiseMin(end) - r, p.origin.cwiseMax(end) + r};
}

}  // namespace

void SceneOptions::Check() const {
  Require(std::isfinite(margin) && margin >= 0 && margin <= 1000,
          "SceneOptions.margin must be in [0, 1000] m", margin);
  Require(std::isfinite(cell_size) && cell_size >= 0.25 && cell_size <= 10,
          "SceneOptions.cell_size must be in [0.25, 10] m", cell_size);
  Require(std::isfinite(max_slope) && max_slope >= 0 && max_slope <= 1,
          "SceneOptions.max_slope must be in [0, 1] m/m", max_slope);
  Require(std::isfinite(undulation) && undulation >= 0 && undulation <= 20,
          "SceneOptions.undulation must be in [0, 20] m", undulation);
  Require(std::isfinite(max_lean) && max_lean >= 0 && max_lean <= 0.5,
          "SceneOptions.max_lean must be in [0, 0.5] rad", max_lean);
  Require(std::isfinite(taper) && taper >= 0 && taper <= 0.1,
          "SceneOptions.taper must be in [0, 0.1] m/m", taper);
  Require(std::isfinite(dbh_log_mean), "SceneOptions.dbh_log_mean must be finite", dbh_log_mean);
  Require(std::isfinite(dbh_log_sd) && dbh_log_sd >= 0, "SceneOptions.dbh_log_sd must be >= 0",
          dbh_log_sd);
  Require(std::isfinite(max_height) && max_height > 2 && max_height <= 150,
          "SceneOptions.max_height must be in (2, 150] m", max_height);
  Require(std::isfinite(crown_density) && crown_density > 0,
          "SceneOptions.crown_density must be > 0 1/m", crown_density);
  Require(max_branches >= 0 && max_branches <= 100, "SceneOptions.max_branches must be in [0, 100]",
          max_branches);
  Require(std::isfinite(branch_min_height) && branch_min_height >= 0,
          "SceneOptions.branch_min_height must be >= 0 m", branch_min_height);
  Require(std::isfinite(shrub_density) && shrub_density >= 0 && shrub_density <= 1,
          "SceneOptions.shrub_density must be in [0, 1] shrubs/m^2", shrub_density);
  Require(std::isfinite(shrub_extinction) && shrub_extinction > 0,
          "SceneOptions.shrub_extinction must be > 0 1/m", shrub_extinction);
}

ForestScene::ForestScene(const std::vector<MapTree>& trees, const SceneOptions& options)
    : options_(options) {
  options_.Check();
  Eigen::Vector2d lo(0, 0), hi(0, 0);
  for (size_t i = 0; i < trees.size(); ++i) {
    const Eigen::Vector2d xy = trees[i].position.head<2>();
    if (!std::isfinite(xy.x()) || !std::isfinite(xy.y())) {
      throw std::invalid_argument("ForestScene: tree id " + std::to_string(trees[i].id) +
                                  " has a non-finite x or y");
    }
    lo = i == 0 ? xy : lo.cwiseMin(xy);
    hi = i == 0 ? xy : hi.cwiseMax(xy);
  }
  const double cell = options_.cell_size;
  min_corner_ = lo - Eigen::Vector2d::Constant(options_.margin + cell);
  nx_ = static_cast<int>(std::ceil((hi.x() - lo.x() + 2 * (options_.margin + cell)) / cell));
  ny_ = static_cast<int>(std::ceil((hi.y() - lo.y() + 2 * (options_.margin + cell)) / cell));
  Require(static_cast<double>(nx_) * ny_ <= 1e8,
          "ForestScene: the scene (trees' extent + 2 margins) has too many cells", 1.0 * nx_ * ny_);
  max_corner_ = min_corner_ + cell * Eigen::Vector2d(nx_, ny_);

  Rng rng(options_.seed);
  BuildTerrain(rng);
  trees_.reserve(trees.size());
  for (const MapTree& tree : trees) BuildTree(tree, rng);
  if (options_.shrubs) BuildShrubs(rng);
  BuildGrid();
}

// A plane of random gradient plus three plane waves, sampled at the grid nodes.
void ForestScene::BuildTerrain(Rng& rng) {
  const Eigen::Vector2d center = 0.5 * (min_corner_ + max_corner_);
  const double direction = Uniform(rng, -M_PI, M_PI);
  const Eigen::Vector2d gradient = Uniform(rng, 0, options_.max_slope) *
                                   Eigen::Vector2d(std::cos(direction), std::sin(direction));
  struct Wave {
    Eigen::Vector2d k;  // rad/m
    double phase;       // rad
  };
  std::array<Wave, 3> waves;
  for (Wave& wave : waves) {
    const double heading = Uniform(rng, -M_PI, M_PI);
    wave.k =
        2 * M_PI / Uniform(rng, 10, 40) * Eigen::Vector2d(std::cos(heading), std::sin(heading));
    wave.phase = Uniform(rng, -M_PI, M_PI);
  }
  heights_.resize(static_cast<size_t>(nx_ + 1) * (ny_ + 1));
  for (int iy = 0; iy <= ny_; ++iy) {
    for (int ix = 0; ix <= nx_; ++ix) {
      const Eigen::Vector2d p = min_corner_ + options_.cell_size * Eigen::Vector2d(ix, iy);
      double z = gradient.dot(p - center);
      for (const Wave& wave : waves) {
        z += options_.undulation / waves.size() * std::sin(wave.k.dot(p) + wave.phase);
      }
      heights_[static_cast<size_t>(iy) * (nx_ + 1) + ix] = z;
    }
  }
}

double ForestScene::TerrainHeight(double x, double y) const {
  const double u = std::clamp((x - min_corner_.x()) / options_.cell_size, 0.0, double(nx_));
  const double v = std::clamp((y - min_corner_.y()) / options_.cell_size, 0.0, double(ny_));
  const int ix = std::min(static_cast<int>(u), nx_ - 1);
  const int iy = std::min(static_cast<int>(v), ny_ - 1);
  const double fu = u - ix, fv = v - iy;
  const double h00 = NodeHeight(ix, iy), h10 = NodeHeight(ix + 1, iy);
  const double h01 = NodeHeight(ix, iy + 1), h11 = NodeHeight(ix + 1, iy + 1);
  return h00 + (h10 - h00) * fu + (h01 - h00) * fv + (h11 - h10 - h01 + h00) * fu * fv;
}

void ForestScene::BuildTree(const MapTree& map_tree, Rng& rng) {
  SceneTree tree;
  tree.id = map_tree.id;
  const double x = map_tree.position.x(), y = map_tree.position.y();
  tree.base = Eigen::Vector3d(x, y, TerrainHeight(x, y));
  const double lean = Uniform(rng, 0, options_.max_lean);
  const double lean_heading = Uniform(rng, -M_PI, M_PI);
  tree.axis = Eigen::Vector3d(std::sin(lean) * std::cos(lean_heading),
                              std::sin(lean) * std::sin(lean_heading), std::cos(lean));
  const double drawn_dbh = std::clamp(
      std::exp(std::normal_distribution<double>(options_.dbh_log_mean, options_.dbh_log_sd)(rng)),
      0.05, 1.2);
  tree.dbh_drawn = !(std::isfinite(map_tree.dbh) && map_tree.dbh > 0);
  tree.dbh = tree.dbh_drawn ? drawn_dbh : map_tree.dbh;
  tree.taper = options_.taper * Uniform(rng, 0.6, 1.4);
  tree.height = std::max(
      2.0, (kBreastHeight + (options_.max_height - kBreastHeight) * (1 - std::exp(-5 * tree.dbh))) *
               Uniform(rng, 0.85, 1.15));
  tree.crown_base = tree.height * Uniform(rng, 0.35, 0.65);
  tree.crown_radius = std::max(0.5, 0.15 * tree.height * Uniform(rng, 0.7, 1.3));
  const int index = static_cast<int>(trees_.size());

  ScenePrimitive stem;
  stem.kind = ScenePrimitive::Kind::kCone;
  stem.label = index;
  stem.tree = index;
  stem.origin = tree.base;
  stem.axis = tree.axis;
  stem.radius = tree.RadiusAt(0);
  stem.radius_slope = -0.5 * tree.taper;
  // The cone ends where it would shrink below 1 cm radius, at the latest at the tree top.
  stem.length = tree.taper > 0 ? std::min(tree.height, (stem.radius - 0.01) / (0.5 * tree.taper))
                               : tree.height;
  primitives_.push_back(stem);

  BuildBranches(tree, index, rng);
  if (options_.crowns) {
    ScenePrimitive crown;
    crown.kind = ScenePrimitive::Kind::kVolume;
    crown.label = kLabelCrown;
    crown.tree = index;
    crown.origin = tree.PointAt(0.5 * (tree.crown_base + tree.height));
    crown.size = Eigen::Vector3d(tree.crown_radius, tree.crown_radius,
                                 0.5 * (tree.height - tree.crown_base));
    crown.extinction = options_.crown_density;
    primitives_.push_back(crown);
  }
  trees_.push_back(tree);
}

// Branches below the crown, pointing 10-50 deg upwards. The same numbers are drawn whether or not
// branches are on, so that switching them off leaves the rest of the scene unchanged.
void ForestScene::BuildBranches(const SceneTree& tree, int index, Rng& rng) {
  const int branches = std::uniform_int_distribution<int>(0, options_.max_branches)(rng);
  const double low = std::min(options_.branch_min_height, tree.crown_base);
  for (int b = 0; b < branches; ++b) {
    const double s = Uniform(rng, low, tree.crown_base);
    const double heading = Uniform(rng, -M_PI, M_PI);
    const double rise = Uniform(rng, 10, 50) * M_PI / 180;
    ScenePrimitive branch;
    branch.kind = ScenePrimitive::Kind::kCylinder;
    branch.label = kLabelBranch;
    branch.tree = index;
    branch.origin = tree.PointAt(s);
    branch.axis = Eigen::Vector3d(std::cos(rise) * std::cos(heading),
                                  std::cos(rise) * std::sin(heading), std::sin(rise));
    branch.length = tree.RadiusAt(s) + Uniform(rng, 0.4, 1.5);
    branch.radius = Uniform(rng, 0.01, 0.03);
    if (options_.branches && s >= options_.branch_min_height) primitives_.push_back(branch);
  }
}

// Shrubs uniform over the scene, but not within 0.5 m of a stem (its breast height stays clear
// in most scans, as in managed stands).
void ForestScene::BuildShrubs(Rng& rng) {
  std::vector<MapTree> stems(trees_.size());
  for (size_t i = 0; i < trees_.size(); ++i) stems[i].position = trees_[i].base;
  const TreeGrid grid(stems);
  const Eigen::Vector2d extent = max_corner_ - min_corner_;
  const int count = static_cast<int>(std::lround(options_.shrub_density * extent.prod()));
  for (int i = 0; i < count; ++i) {
    ScenePrimitive shrub;
    shrub.kind = ScenePrimitive::Kind::kVolume;
    shrub.label = kLabelShrub;
    const Eigen::Vector2d xy(Uniform(rng, min_corner_.x(), max_corner_.x()),
                             Uniform(rng, min_corner_.y(), max_corner_.y()));
    const double radius = Uniform(rng, 0.3, 1.0);
    shrub.size = Eigen::Vector3d(radius, radius * Uniform(rng, 0.7, 1.3), Uniform(rng, 0.3, 0.8));
    shrub.origin =
        Eigen::Vector3d(xy.x(), xy.y(), TerrainHeight(xy.x(), xy.y()) + 0.6 * shrub.size.z());
    shrub.extinction = options_.shrub_extinction;
    bool clear = true;
    const std::vector<int> near = trees_.empty()
                                      ? std::vector<int>()
                                      : grid.InRadius(xy, shrub.size.head<2>().maxCoeff() + 2.0);
    for (int t : near) {
      const double gap = (trees_[t].base.head<2>() - xy).norm() - trees_[t].RadiusAt(0) -
                         shrub.size.head<2>().maxCoeff();
      clear = clear && gap >= 0.5;
    }
    if (clear) primitives_.push_back(shrub);
  }
}

void ForestScene::BuildGrid() {
  const double cell = options_.cell_size;
  const size_t cells = static_cast<size_t>(nx_) * ny_;
  cell_top_.assign(cells, -std::numeric_limits<float>::infinity());
  for (int iy = 0; iy < ny_; ++iy) {
    for (int ix = 0; ix < nx_; ++ix) {
      cell_top_[static_cast<size_t>(iy) * nx_ + ix] =
          static_cast<float>(std::max({NodeHeight(ix, iy), NodeHeight(ix + 1, iy),
                                       NodeHeight(ix, iy + 1), NodeHeight(ix + 1, iy + 1)}));
    }
  }
  auto cell_range = [&](const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    const int x0 =
        std::clamp(int(std::floor((lo.x() - kBoundsPad - min_corner_.x()) / cell)), 0, nx_ - 1);
    const int y0 =
        std::clamp(int(std::floor((lo.y() - kBoundsPad - min_corner_.y()) / cell)), 0, ny_ - 1);
    const int x1 =
        std::clamp(int(std::floor((hi.x() + kBoundsPad - min_corner_.x()) / cell)), 0, nx_ - 1);
    const int y1 =
        std::clamp(int(std::floor((hi.y() + kBoundsPad - min_corner_.y()) / cell)), 0, ny_ - 1);
    return std::array<int, 4>{x0, y0, x1, y1};
  };
  std::vector<int> counts(cells + 1, 0);
  primitive_z_.clear();
  for (const ScenePrimitive& p : primitives_) {
    const auto [lo, hi] = PrimitiveBounds(p);
    primitive_z_.emplace_back(lo.z() - kBoundsPad, hi.z() + kBoundsPad);
    const auto r = cell_range(lo, hi);
    for (int y = r[1]; y <= r[3]; ++y) {
      for (int x = r[0]; x <= r[2]; ++x) {
        const size_t c = static_cast<size_t>(y) * nx_ + x;
        ++counts[c + 1];
        cell_top_[c] = std::max(cell_top_[c], static_cast<float>(hi.z() + kBoundsPad));
      }
    }
  }
  scene_top_ = *std::max_element(cell_top_.begin(), cell_top_.end());
  cell_start_.assign(cells + 1, 0);
  for (size_t c = 0; c < cells; ++c) cell_start_[c + 1] = cell_start_[c] + counts[c + 1];
  cell_items_.assign(cell_start_.back(), 0);
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  for (size_t i = 0; i < primitives_.size(); ++i) {
    const auto [lo, hi] = PrimitiveBounds(primitives_[i]);
    const auto r = cell_range(lo, hi);
    for (int y = r[1]; y <= r[3]; ++y) {
      for (int x = r[0]; x <= r[2]; ++x) {
        cell_items_[fill[static_cast<size_t>(y) * nx_ + x]++] = static_cast<int>(i);
      }
    }
  }
}

}  // namespace forestmap::algorithms
