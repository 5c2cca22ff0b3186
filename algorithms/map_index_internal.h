#pragma once
// Internal layout of MapIndex, shared by the index builder and the relocalizer only.

#include <array>
#include <memory>
#include <vector>

#include "algorithms/kdtree.h"
#include "algorithms/map_index.h"
#include "algorithms/triangles.h"

namespace forestmap::algorithms {

class MapIndexImpl {
 public:
  std::vector<MapTree> trees;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // map frame; kd coordinates are relative
  std::unique_ptr<KdTree<float, 2>> positions;       // tree i at positions->point(i) + origin
  std::vector<std::array<uint32_t, 3>> triangle_vertices;  // canonical A, B, C
  std::unique_ptr<KdTree<float, 3>> triangle_keys;          // sorted side lengths
  TriangleOptions triangle_options;
  bool has_z = false;
  bool has_dbh = false;

  Eigen::Vector2d Xy(uint32_t i) const {
    const auto& p = positions->point(i);
    return Eigen::Vector2d(p[0], p[1]);
  }
};

}  // namespace forestmap::algorithms
