#pragma once
// "Is there a map tree within r of this point?" in a few nanoseconds: a bitmap of the cells whose
// centre lies within r of a tree, kept in 64 x 64-cell tiles that exist only near trees (a flat
// hash table of tiles), so memory follows the trees, not the map's extent. Answers are exact up
// to half a cell diagonal; the relocalizer uses it to reject wrong pose hypotheses before any
// exact nearest-neighbour search.

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace forestmap::algorithms {

class OccupancyGrid {
 public:
  // `points` in metres; `radius` and `resolution` (cell edge) in metres.
  OccupancyGrid(const std::vector<Eigen::Vector2d>& points, double radius, double resolution);

  bool Near(double x, double y) const {
    const int64_t cx = static_cast<int64_t>(std::floor(x * inverse_resolution_));
    const int64_t cy = static_cast<int64_t>(std::floor(y * inverse_resolution_));
    const int32_t tile = Find(TileKey(cx >> kTileBits, cy >> kTileBits));
    if (tile < 0) return false;
    return (tiles_[tile].rows[cy & kTileMask] >> (cx & kTileMask)) & 1u;
  }

  // Share of the cells of existing tiles that are occupied: about the chance that a point
  // dropped among the trees lands within `radius` of one.
  double occupied_fraction() const { return occupied_fraction_; }
  size_t MemoryBytes() const {
    return tiles_.capacity() * sizeof(Tile) + keys_.capacity() * sizeof(uint64_t) +
           slots_.capacity() * sizeof(int32_t);
  }

 private:
  static constexpr int kTileBits = 6;  // 64 x 64 cells a tile
  static constexpr int64_t kTileMask = (1 << kTileBits) - 1;
  struct Tile {
    uint64_t rows[64] = {};
  };
  static uint64_t TileKey(int64_t tx, int64_t ty) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(tx)) << 32) |
           static_cast<uint32_t>(ty);
  }
  int32_t Find(uint64_t key) const {
    size_t i = (key * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
    while (slots_[i] >= 0) {
      if (keys_[i] == key) return slots_[i];
      i = (i + 1) & mask_;
    }
    return -1;
  }
  Tile& Insert(uint64_t key);

  double inverse_resolution_ = 1;
  double occupied_fraction_ = 0;
  std::vector<Tile> tiles_;
  std::vector<uint64_t> keys_;   // open addressing, linear probing
  std::vector<int32_t> slots_;   // tile index, -1 = free
  size_t mask_ = 0;
};

}  // namespace forestmap::algorithms
