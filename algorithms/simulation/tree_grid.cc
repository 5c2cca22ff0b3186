#include "algorithms/simulation/tree_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "algorithms/core/check.h"

namespace forestmap::algorithms {

TreeGrid::TreeGrid(const std::vector<MapTree>& trees) {
  if (trees.empty()) return;
  min_corner_ = max_corner_ = trees.front().position.head<2>();
  for (const MapTree& tree : trees) {
    if (!tree.position.head<2>().allFinite()) {
      Require(false, "TreeGrid: tree " + std::to_string(tree.id) + " has a non-finite x or y, x",
              tree.position.x());
    }
    min_corner_ = min_corner_.cwiseMin(tree.position.head<2>());
    max_corner_ = max_corner_.cwiseMax(tree.position.head<2>());
  }
  const Eigen::Vector2d extent = (max_corner_ - min_corner_).cwiseMax(1e-3);
  const double n = static_cast<double>(trees.size());
  cell_size_ = std::max(std::sqrt(extent.prod() * 2 / n), 1e-3);  // ~2 trees per cell
  while ((extent.x() / cell_size_ + 1) * (extent.y() / cell_size_ + 1) > 4 * n + 64) {
    cell_size_ *= 1.5;  // thin, elongated extents: bound the number of cells
  }
  nx_ = static_cast<int>(extent.x() / cell_size_) + 1;
  ny_ = static_cast<int>(extent.y() / cell_size_) + 1;
  std::vector<int> cell_of(trees.size());
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (size_t i = 0; i < trees.size(); ++i) {
    cell_of[i] = CellY(trees[i].position.y()) * nx_ + CellX(trees[i].position.x());
    ++cell_start_[cell_of[i] + 1];
  }
  std::partial_sum(cell_start_.begin(), cell_start_.end(), cell_start_.begin());
  std::vector<int> fill(cell_start_.begin(), cell_start_.end() - 1);
  index_.resize(trees.size());
  xy_.resize(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) {
    const int slot = fill[cell_of[i]]++;
    index_[slot] = static_cast<int>(i);
    xy_[slot] = trees[i].position.head<2>();
  }
}

int TreeGrid::CellX(double x) const {
  return static_cast<int>(std::clamp(std::floor((x - min_corner_.x()) / cell_size_), 0.0,
                                     static_cast<double>(nx_ - 1)));
}

int TreeGrid::CellY(double y) const {
  return static_cast<int>(std::clamp(std::floor((y - min_corner_.y()) / cell_size_), 0.0,
                                     static_cast<double>(ny_ - 1)));
}

std::vector<int> TreeGrid::InRadius(const Eigen::Vector2d& center, double radius) const {
  std::vector<int> result;
  if (nx_ == 0 || !(radius >= 0)) return result;
  const int x0 = CellX(center.x() - radius), x1 = CellX(center.x() + radius);
  const int y0 = CellY(center.y() - radius), y1 = CellY(center.y() + radius);
  for (int y = y0; y <= y1; ++y) {
    for (int slot = cell_start_[y * nx_ + x0]; slot < cell_start_[y * nx_ + x1 + 1]; ++slot) {
      if ((xy_[slot] - center).squaredNorm() <= radius * radius) result.push_back(index_[slot]);
    }
  }
  return result;
}

int TreeGrid::Nearest(const Eigen::Vector2d& center, int exclude) const {
  if (nx_ == 0) return -1;
  const int cx = CellX(center.x()), cy = CellY(center.y());
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  auto visit = [&](int x, int y) {
    for (int slot = cell_start_[y * nx_ + x]; slot < cell_start_[y * nx_ + x + 1]; ++slot) {
      const double d2 = (xy_[slot] - center).squaredNorm();
      if (index_[slot] != exclude && d2 < best_d2) best_d2 = d2, best = index_[slot];
    }
  };
  // Rings of cells at Chebyshev distance k; trees beyond ring k are >= k cells away.
  for (int k = 0; k <= std::max(nx_, ny_); ++k) {
    for (int y = std::max(cy - k, 0); y <= std::min(cy + k, ny_ - 1); ++y) {
      const bool full_row = std::abs(y - cy) == k;
      for (int x = cx - k; x <= cx + k; x += (full_row ? 1 : 2 * k)) {
        if (x >= 0 && x < nx_) visit(x, y);
        if (k == 0) break;
      }
    }
    if (best >= 0 && std::sqrt(best_d2) <= k * cell_size_) break;
  }
  return best;
}

}  // namespace forestmap::algorithms
