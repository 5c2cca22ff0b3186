#pragma once
// Internal layout of MapIndex, shared by the index builder and the relocalizer only.

#include <array>
#include <memory>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/occupancy_grid.h"
#include "algorithms/relocalization/triangle_table.h"

namespace forestmap::algorithms {

class MapIndexImpl {
 public:
  std::vector<MapTree> trees;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // map frame; kd coordinates are relative
  std::unique_ptr<KdTree<float, 2>> positions;       // tree i at positions->point(i) + origin
  std::unique_ptr<TriangleTable> triangles;          // constellation keys (kd coordinates)
  std::unique_ptr<OccupancyGrid> occupancy;          // kd coordinates: near a tree?
  TriangleOptions triangle_options;
  bool has_z = false;
  bool has_dbh = false;

  Eigen::Vector2d Xy(uint32_t i) const {
    const auto& p = positions->point(i);
    return Eigen::Vector2d(p[0], p[1]);
  }
};

}  // namespace forestmap::algorithms
