#include "algorithms/occupancy_grid.h"

#include <algorithm>
#include <stdexcept>

namespace forestmap::algorithms {

OccupancyGrid::OccupancyGrid(const std::vector<Eigen::Vector2d>& points, double radius,
                             double resolution)
    : inverse_resolution_(1.0 / resolution) {
  if (!(radius > 0 && resolution > 0 && resolution <= radius)) {
    throw std::invalid_argument("OccupancyGrid: need 0 < resolution <= radius");
  }
  // The cells of each point's disk: their centres within `radius`.
  const int reach = static_cast<int>(std::ceil(radius * inverse_resolution_));
  auto for_each_cell = [&](const Eigen::Vector2d& p, auto&& fn) {
    const int64_t px = static_cast<int64_t>(std::floor(p.x() * inverse_resolution_));
    const int64_t py = static_cast<int64_t>(std::floor(p.y() * inverse_resolution_));
    for (int64_t cy = py - reach; cy <= py + reach; ++cy) {
      for (int64_t cx = px - reach; cx <= px + reach; ++cx) {
        const Eigen::Vector2d centre((cx + 0.5) * resolution, (cy + 0.5) * resolution);
        if ((centre - p).squaredNorm() <= radius * radius) fn(cx, cy);
      }
    }
  };
  // The tiles that will exist, then a table twice their number (a power of two).
  std::vector<uint64_t> needed;  // the tiles under each point's bounding box of cells
  for (const Eigen::Vector2d& p : points) {
    const int64_t px = static_cast<int64_t>(std::floor(p.x() * inverse_resolution_));
    const int64_t py = static_cast<int64_t>(std::floor(p.y() * inverse_resolution_));
    for (int64_t ty = (py - reach) >> kTileBits; ty <= (py + reach) >> kTileBits; ++ty) {
      for (int64_t tx = (px - reach) >> kTileBits; tx <= (px + reach) >> kTileBits; ++tx) {
        needed.push_back(TileKey(tx, ty));
      }
    }
  }
  std::sort(needed.begin(), needed.end());
  needed.erase(std::unique(needed.begin(), needed.end()), needed.end());
  size_t capacity = 16;
  while (capacity < 2 * needed.size()) capacity *= 2;
  mask_ = capacity - 1;
  keys_.assign(capacity, 0);
  slots_.assign(capacity, -1);
  tiles_.reserve(needed.size());
  for (uint64_t key : needed) Insert(key);

  size_t occupied = 0;
  for (const Eigen::Vector2d& p : points) {
    for_each_cell(p, [&](int64_t cx, int64_t cy) {
      uint64_t& row = tiles_[Find(TileKey(cx >> kTileBits, cy >> kTileBits))].rows[cy & kTileMask];
      const uint64_t bit = uint64_t{1} << (cx & kTileMask);
      occupied += (row & bit) == 0;
      row |= bit;
    });
  }
  occupied_fraction_ =
      tiles_.empty() ? 0.0 : static_cast<double>(occupied) / (tiles_.size() * 64.0 * 64.0);
}

OccupancyGrid::Tile& OccupancyGrid::Insert(uint64_t key) {
  size_t i = (key * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
  while (slots_[i] >= 0 && keys_[i] != key) i = (i + 1) & mask_;
  if (slots_[i] < 0) {
    keys_[i] = key;
    slots_[i] = static_cast<int32_t>(tiles_.size());
    tiles_.emplace_back();
  }
  return tiles_[slots_[i]];
}

}  // namespace forestmap::algorithms
