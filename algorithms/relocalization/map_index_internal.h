#pragma once
// Internal layout of MapIndex, shared by the index builder and the relocalizer only.

#include <array>
#include <memory>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/relocalization/coverage.h"
#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/occupancy_grid.h"
#include "algorithms/relocalization/triangle_levels.h"
#include "algorithms/relocalization/triangle_table.h"

namespace forestmap::algorithms {

class MapIndexImpl {
 public:
  std::vector<MapTree> trees;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // map frame; kd coordinates are relative
  std::unique_ptr<KdTree<float, 2>> positions;       // tree i at positions->point(i) + origin
  // Constellation keys (kd coordinates), one table per level (triangle_levels.h); null when a
  // level has no triangles.
  std::vector<std::unique_ptr<TriangleTable>> tables;
  std::unique_ptr<OccupancyGrid> occupancy;  // kd coordinates: near a tree?
  std::unique_ptr<CoverageGrid> coverage;    // kd coordinates: mapped forest?
  std::vector<Polygon> coverage_outline;     // map frame: the boundary, else the derived one
  bool coverage_derived = true;
  TriangleLevels levels;
  // Share of the trees whose level is at least b, by band b: the chance that a query triangle
  // of that band lies where the map indexes triangles that long.
  std::vector<double> band_share;
  bool has_z = false;
  bool has_dbh = false;

  // The local chance that a point lands within the occupancy radius of a map tree: the
  // occupied share of the covered part around it; 0 outside the coverage (no evidence there).
  double ChanceAt(const Eigen::Vector2d& p) const {
    return coverage->Covered(p.x(), p.y()) ? occupancy->OccupiedFractionAt(p.x(), p.y()) : 0.0;
  }
  bool Covered(const Eigen::Vector2d& p) const { return coverage->Covered(p.x(), p.y()); }

  Eigen::Vector2d Xy(uint32_t i) const {
    const auto& p = positions->point(i);
    return Eigen::Vector2d(p[0], p[1]);
  }
};

}  // namespace forestmap::algorithms
