#pragma once
// "Is there a map tree within r of this point?" in a few nanoseconds: a bitmap of the cells whose
// centre lies within r of a tree, kept in 64 x 64-cell tiles that exist only near trees, found
// through a dense directory over the tiles' bounding box (a flat hash table when that box is
// mostly empty), so memory follows the trees, not the map's extent. Answers are exact up
// to half a cell diagonal; the relocalizer uses it to reject wrong pose hypotheses before any
// exact nearest-neighbour search.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <vector>

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

  // The same share in the tile around (x, y) (64 cells across): the local chance.
  double OccupiedFractionAt(double x, double y) const {
    const int64_t cx = static_cast<int64_t>(std::floor(x * inverse_resolution_));
    const int64_t cy = static_cast<int64_t>(std::floor(y * inverse_resolution_));
    const int32_t tile = Find(TileKey(cx >> kTileBits, cy >> kTileBits));
    return tile < 0 ? 0.0 : tiles_[tile].occupied / (64.0 * 64.0);
  }
  size_t MemoryBytes() const {
    return tiles_.capacity() * sizeof(Tile) + directory_.capacity() * sizeof(int32_t) +
           hash_.capacity() * sizeof(HashEntry);
  }

 private:
  static constexpr int kTileBits = 6;                // 64 x 64 cells a tile
  static constexpr double kMaxCell = 68719476736.0;  // 2^36: |cell index| bound, tiles fit int32
  static constexpr int64_t kTileMask = (1 << kTileBits) - 1;
  struct Tile {
    uint64_t rows[64] = {};
    int occupied = 0;  // cells set
  };
  static uint64_t TileKey(int64_t tx, int64_t ty) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(tx)) << 32) | static_cast<uint32_t>(ty);
  }
  int32_t Find(uint64_t key) const {
    if (!directory_.empty()) {
      const int64_t tx = static_cast<int32_t>(key >> 32) - min_tx_;
      const int64_t ty = static_cast<int32_t>(key & 0xFFFFFFFFu) - min_ty_;
      if (tx < 0 || ty < 0 || tx >= width_ || ty >= height_) return -1;
      return directory_[ty * width_ + tx];
    }
    size_t i = (key * 0x9E3779B97F4A7C15ull) >> 17 & mask_;
    while (hash_[i].tile >= 0) {
      if (hash_[i].key == key) return hash_[i].tile;
      i = (i + 1) & mask_;
    }
    return -1;
  }
  void Index(const std::vector<uint64_t>& keys);  // sorted, unique tile keys

  struct HashEntry {
    uint64_t key = 0;
    int32_t tile = -1;  // -1 = free
  };
  double inverse_resolution_ = 1;
  double occupied_fraction_ = 0;
  std::vector<Tile> tiles_;
  std::vector<int32_t> directory_;  // dense: tile index by (ty - min_ty_, tx - min_tx_), -1 = none
  int64_t min_tx_ = 0, min_ty_ = 0, width_ = 0, height_ = 0;
  std::vector<HashEntry> hash_;  // sparse: open addressing, linear probing
  size_t mask_ = 0;
};

}  // namespace forestmap::algorithms
