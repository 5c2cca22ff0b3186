#pragma once

#include <Eigen/Core>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

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

}  // namespace forestmap::algorithms
