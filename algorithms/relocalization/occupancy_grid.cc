#include "algorithms/relocalization/occupancy_grid.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

OccupancyGrid::OccupancyGrid(const std::vector<Eigen::Vector2d>& points, double radius,
                             double resolution, const CoveredShare& covered_share)
    : inverse_resolution_(1.0 / resolution), radius_(radius) {
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
        needed.push_back(TileDirectory::Key(tx, ty));
      }
    }
  }
  std::sort(needed.begin(), needed.end());
  needed.erase(std::unique(needed.begin(), needed.end()), needed.end());
  tiles_.resize(needed.size());
  std::vector<std::pair<uint64_t, int32_t>> entries(needed.size());
  for (size_t i = 0; i < needed.size(); ++i) entries[i] = {needed[i], static_cast<int32_t>(i)};
  directory_.Index(entries);

  size_t occupied = 0;
  for (const Eigen::Vector2d& p : points) {
    for_each_cell(p, [&](int64_t cx, int64_t cy) {
      Tile& tile = tiles_[Find(TileDirectory::Key(cx >> kTileBits, cy >> kTileBits))];
      uint64_t& row = tile.rows[cy & kTileMask];
      const uint64_t bit = uint64_t{1} << (cx & kTileMask);
      if ((row & bit) == 0) ++occupied, ++tile.occupied;
      row |= bit;
    });
  }
  occupied_fraction_ =
      tiles_.empty() ? 0.0 : static_cast<double>(occupied) / (tiles_.size() * 64.0 * 64.0);
  const double side = 64.0 * resolution;
  for (const auto& [key, index] : entries) {
    Tile& tile = tiles_[index];
    const double share = covered_share
                             ? covered_share(static_cast<int32_t>(key >> 32) * side,
                                             static_cast<int32_t>(key & 0xFFFFFFFFu) * side, side)
                             : 1.0;
    tile.chance = static_cast<float>(
        std::min(1.0, tile.occupied / (64.0 * 64.0) / std::max(share, kMinCoveredShare)));
  }
}

}  // namespace forestmap::algorithms
