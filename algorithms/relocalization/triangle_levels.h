#pragma once
// Density-adaptive triangle keys: a forest district mixes stands whose densities differ
// thirtyfold, and one triangle side for the whole map either loses the sparse stands' triangles
// or floods the search with the dense ones'. Every map tree gets a level from its local spacing
// (the distance to its kSpacingNeighbour-th nearest tree, median over a square cell); the sides
// of the levels grow geometrically; a triangle belongs to the lowest level of its three trees
// and is indexed when its sides fit that level, in the table of its size band. A query
// estimates its own spacing the same way and builds triangles up to the side that suggests, so
// a sparse stand beside a dense one is indexed and searched as if it were alone.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/relocalization/page_vector.h"
#include "algorithms/relocalization/triangles.h"

namespace forestmap::algorithms {

inline constexpr int kSpacingNeighbour = 6;  // local spacing: distance to the 6th nearest tree

struct TriangleLevels {
  double base_side = 1.0;   // m, longest side of a level-0 triangle
  double ratio = M_SQRT2;   // side ratio of consecutive levels
  double max_side = 30.0;   // m, longest side of the last level's triangles
  double min_side = 0.5;    // m, shortest side of every triangle
  double scale = 1.0;       // a tree's wanted side = scale x its local spacing (per map) ...
  double floor_side = 3.5;  // m, ... but at least this (a drone misses trees), budget allowing
  int count() const;        // levels from base_side to max_side
  double Side(int level) const;
  // The level whose side is nearest, on a log scale, to max(floor_side, scale x spacing) (m).
  int LevelFor(double spacing) const;
};

// A sparse stand's trees may have more triangles each than the map's per-tree budget: a view
// holds few of them, and only an indexed triangle of three seen trees finds the pose. The
// budget grows with the square of the local spacing (about triangles per square metre instead
// of per tree) above `spacing_from`, by at most `max_factor`. Sparse stands hold few of a
// district's trees, so the index grows little.
struct SparseBudget {
  double spacing_from = 0;              // m, local spacing where the growth starts (0: none)
  double max_factor = 1;                // largest factor on the per-tree budget
  double Factor(double spacing) const;  // spacing in m
};

// The map's trees by square cell, with each cell's local spacing (m): the median, over up to 15
// of its trees, of the distance to the kSpacingNeighbour-th nearest tree.
class SpacingCells {
 public:
  SpacingCells(const KdTree<float, 2>& kd, double cell, int threads);
  // Every tree's level: its cell's LevelFor (of the spacing times the fourth root of the sparse
  // factor F of the cell's spacing), lowered while the cell's sampled trees have more than
  // F x `cap` triangles each (a third of the triangles they are a vertex of).
  std::vector<uint8_t> Levels(const KdTree<float, 2>& kd, const TriangleLevels& levels, double cap,
                              const SparseBudget& sparse = {}) const;
  // Every tree's spacing (m): its cell's, by tree index.
  std::vector<float> TreeSpacing() const;

 private:
  void Smooth();
  std::vector<std::pair<uint64_t, uint32_t>> by_cell_;  // (cell key, tree), sorted
  std::vector<size_t> runs_;                            // start of each cell's run, and the end
  std::vector<float> spacing_;                          // m, by cell
  int threads_ = 1;
};

// A query's spacing (m): the median over its `count` first points (nearest the sensor) of the
// distance to the kSpacingNeighbour-th nearest other point (the farthest, with fewer points).
double QuerySpacing(const std::vector<Eigen::Vector2d>& points, size_t count);

// The triangles anchored at points [begin, end) (each triangle once, from its smallest index),
// by band: a triangle is kept when all its sides lie within [levels.min_side,
// levels.Side(level)], its level being the lowest of its points' `level`; its band is the
// lowest level whose side its longest side fits (so a query triangle has one band to look in,
// two near a band's edge, whatever the density where it lies). Page-mapped buffers
// (page_vector.h): the index build calls this on worker threads.
std::vector<PageVector<Triangle>> EnumerateLevelled(const KdTree<float, 2>& kd,
                                                    const std::vector<Eigen::Vector2d>& points,
                                                    const std::vector<uint8_t>& level,
                                                    const TriangleLevels& levels, size_t begin,
                                                    size_t end);

}  // namespace forestmap::algorithms
