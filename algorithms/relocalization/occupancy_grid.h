#pragma once
// "Is there a map tree within r of this point?" in a few nanoseconds: a bitmap of the cells whose
// centre lies within r of a tree, kept in 64 x 64-cell tiles that exist only near trees, found
// through a dense directory over the tiles' bounding box (a flat hash table when that box is
// mostly empty: tile_directory.h), so memory follows the trees, not the map's extent. Answers are
// exact up to half a cell diagonal; the relocalizer uses it to reject wrong pose hypotheses before
// any exact nearest-neighbour search.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include "algorithms/relocalization/tile_directory.h"

namespace forestmap::algorithms {

class OccupancyGrid {
 public:
  // The share of a square (its lower corner x0, y0 and side, m) that the map covers.
  using CoveredShare = std::function<double(double x0, double y0, double side)>;

  // `points` in metres; `radius` and `resolution` (cell edge) in metres. `covered_share` (none:
  // every tile wholly covered) makes each tile's chance its occupied share of the covered part:
  // beyond a survey's edge the map has no trees because nobody mapped them, not because there
  // are none.
  OccupancyGrid(const std::vector<Eigen::Vector2d>& points, double radius, double resolution,
                const CoveredShare& covered_share = nullptr);

  bool Near(double x, double y) const {
    const int64_t cx = FloorCell(x * inverse_resolution_);
    const int64_t cy = FloorCell(y * inverse_resolution_);
    const int32_t tile = Find(TileDirectory::Key(cx >> kTileBits, cy >> kTileBits));
    if (tile < 0) return false;
    return (tiles_[tile].rows[cy & kTileMask] >> (cx & kTileMask)) & 1u;
  }

  // Share of the cells of existing tiles that are occupied: about the chance that a point
  // dropped among the trees lands within `radius` of one.
  double occupied_fraction() const { return occupied_fraction_; }

  // The same share in the tile around (x, y) (64 cells across), of the part of the tile the
  // map covers: the local chance that a point of the mapped forest there lands
  // within `radius` of a tree.
  double OccupiedFractionAt(double x, double y) const {
    const int64_t cx = FloorCell(x * inverse_resolution_);
    const int64_t cy = FloorCell(y * inverse_resolution_);
    const int32_t tile = directory_.Find(TileDirectory::Key(cx >> kTileBits, cy >> kTileBits));
    return tile < 0 ? 0.0 : tiles_[tile].chance;
  }

  double radius() const { return radius_; }
  size_t MemoryBytes() const { return tiles_.capacity() * sizeof(Tile) + directory_.MemoryBytes(); }

 private:
  static constexpr int kTileBits = 6;                // 64 x 64 cells a tile
  static constexpr double kMaxCell = 68719476736.0;  // 2^36: |cell index| bound, tiles fit int32
  static constexpr int64_t kTileMask = (1 << kTileBits) - 1;
  static constexpr double kMinCoveredShare = 1.0 / 64;  // of a tile: a sliver counts as this
  struct Tile {
    uint64_t rows[64] = {};
    int occupied = 0;  // cells set
    float chance = 0;  // occupied share of the covered part of the tile
  };
  int32_t Find(uint64_t key) const { return directory_.Find(key); }

  double inverse_resolution_ = 1;
  double radius_ = 0;
  double occupied_fraction_ = 0;
  std::vector<Tile> tiles_;
  TileDirectory directory_;
};

}  // namespace forestmap::algorithms
