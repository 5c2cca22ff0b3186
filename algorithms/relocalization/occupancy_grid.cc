#include "algorithms/relocalization/occupancy_grid.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

OccupancyGrid::OccupancyGrid(const std::vector<Eigen::Vector2d>& points, double radius,
                             double resolution)
    : inverse_resolution_(1.0 / resolution) {
  if (!(radius > 0 && resolution > 0 && resolution <= radius)) {
    throw std::invalid_argument("OccupancyGrid: need 0 < resolution <= radius");
  }
  // Tile coordinates are 32-bit: a point beyond that range (or not finite) would have no tile.
  for (size_t i = 0; i < points.size(); ++i) {
    const double cx = points[i].x() * inverse_resolution_, cy = points[i].y() * inverse_resolution_;
    if (!(std::abs(cx) < kMaxCell && std::abs(cy) < kMaxCell)) {
      throw std::invalid_argument("OccupancyGrid: point " + std::to_string(i) +
                                  " lies beyond the grid's range of " + std::to_string(kMaxCell) +
                                  " cells from the origin");
    }
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
  tiles_.resize(needed.size());
  Index(needed);

  size_t occupied = 0;
  for (const Eigen::Vector2d& p : points) {
    for_each_cell(p, [&](int64_t cx, int64_t cy) {
      Tile& tile = tiles_[Find(TileKey(cx >> kTileBits, cy >> kTileBits))];
      uint64_t& row = tile.rows[cy & kTileMask];
      const uint64_t bit = uint64_t{1} << (cx & kTileMask);
      if ((row & bit) == 0) ++occupied, ++tile.occupied;
      row |= bit;
    });
  }
  occupied_fraction_ =
      tiles_.empty() ? 0.0 : static_cast<double>(occupied) / (tiles_.size() * 64.0 * 64.0);
}

void OccupancyGrid::Index(const std::vector<uint64_t>& keys) {
  if (keys.empty()) return;
  int64_t max_tx = INT64_MIN, max_ty = INT64_MIN;
  min_tx_ = min_ty_ = INT64_MAX;
  for (uint64_t key : keys) {
    const int64_t tx = static_cast<int32_t>(key >> 32),
                  ty = static_cast<int32_t>(key & 0xFFFFFFFFu);
    min_tx_ = std::min(min_tx_, tx), max_tx = std::max(max_tx, tx);
    min_ty_ = std::min(min_ty_, ty), max_ty = std::max(max_ty, ty);
  }
  // Dense when the box holds at most 64 directory entries per tile (256 bytes against a tile's
  // 520): lookups then cost one memory access less.
  const double box = static_cast<double>(max_tx - min_tx_ + 1) * (max_ty - min_ty_ + 1);
  if (box <= 64.0 * keys.size()) {
    width_ = max_tx - min_tx_ + 1;
    height_ = max_ty - min_ty_ + 1;
    directory_.assign(static_cast<size_t>(box), -1);
    for (size_t i = 0; i < keys.size(); ++i) {
      const int64_t tx = static_cast<int32_t>(keys[i] >> 32),
                    ty = static_cast<int32_t>(keys[i] & 0xFFFFFFFFu);
      directory_[(ty - min_ty_) * width_ + (tx - min_tx_)] = static_cast<int32_t>(i);
    }
    return;
  }
  size_t capacity = 16;
  while (capacity < 2 * keys.size()) capacity *= 2;
  mask_ = capacity - 1;
  hash_.assign(capacity, HashEntry{});
  for (size_t t = 0; t < keys.size(); ++t) {
    size_t i = (keys[t] * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
    while (hash_[i].tile >= 0) i = (i + 1) & mask_;
    hash_[i] = {keys[t], static_cast<int32_t>(t)};
  }
}

}  // namespace forestmap::algorithms
