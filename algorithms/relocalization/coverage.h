#pragma once
// What a map covers: the area its survey mapped, where a tree the map lacks is evidence that a
// pose is wrong. Beyond it the map says nothing: a drone at the edge of its map, or a plot scan
// that reaches into the neighbour's plot, sees trees nobody mapped.
//
// A map's coverage is its survey boundary when one is given (polygons with holes). Without one
// it is derived from the trees (DeriveCoverage): the alpha shape of the trees (Edelsbrunner,
// Kirkpatrick & Seidel 1983), the union of the Delaunay triangles of the map's trees whose
// circumcircle (an empty disc: no tree inside) has a radius of at most alpha_spacings times the
// local spacing (the distance to the 6th nearest tree, median over 25 m cells, as the triangle
// index measures it). The rule and its limits:
//   - A triangle's circumcircle is a disc without trees. In a Poisson forest of density rho the
//     6th-neighbour spacing s satisfies pi rho s^2 ~ 5.5, so a disc of radius 2 s holds
//     pi rho (2 s)^2 ~ 22 trees on average, and a Delaunay triangle's circumradius exceeds it
//     with probability (1 + 22) e^-22 ~ 6e-9: a million-tree map (2 million triangles) has a
//     hole by chance with probability ~1%. A gap wider than about two spacings is a hole: a
//     clearing, a road, or unmapped ground; its trees are neither support nor evidence.
//   - The boundary runs through the outermost trees: the strip between them and the survey's
//     real edge (about half a spacing) counts as unmapped.
//   - Stands closer than about two spacings merge; a concave notch narrower than that is filled.
//   - Every map tree's disc of tree_margin (the inlier gate) is covered too, with an explicit
//     boundary as well, so that a detection matched to a map tree always counts.
// For lookups the coverage is rasterized (CoverageGrid): cells of `resolution` whose centre is
// covered.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "algorithms/core/polygon.h"
#include "algorithms/relocalization/tile_directory.h"

namespace forestmap::algorithms {

struct CoverageOptions {
  double alpha_spacings = 2.0;  // alpha shape radius, in local spacings (see above)
  double resolution = 0.5;      // m, raster cell
  // m, every map tree's disc of this radius is covered (the relocalizer's inlier gate); the
  // raster widens it by half a cell diagonal.
  double tree_margin = 0.4;
  void Check() const;  // throws std::invalid_argument
};

// The coverage the trees at `points` (m) say their survey had: their alpha shape with a radius of
// options.alpha_spacings x each point's local `spacing` (m).
std::vector<Polygon> DeriveCoverage(const std::vector<Eigen::Vector2d>& points,
                                    const std::vector<float>& spacing,
                                    const CoverageOptions& options);

// The alpha shape of `points` (m) with a radius per point: a Delaunay triangle is kept when its
// circumradius is at most the largest `alpha` of its vertices. Polygons with holes, outer rings
// counter-clockwise, holes clockwise, in the points' frame; vertices are points.
std::vector<Polygon> AlphaShape(const std::vector<Eigen::Vector2d>& points,
                                const std::vector<double>& alpha);

// "Is this point covered?" in a few nanoseconds: a bitmap of 64 x 64-cell tiles, tiles wholly
// covered sharing one stored tile, found through a tile directory.
class CoverageGrid {
 public:
  // The cells whose centre lies in any of `polygons` (even-odd within each) or within `margin`
  // (m) of a point. Same frame for both (m). The cells are `resolution` wide, coarser when the
  // polygons hold more than 2^27 of them (over 30 km^2 at 0.5 m) or their rings cross more than
  // 2^22 rows of them (over 2,000 km of north-south edges at 0.5 m): time and memory stay bounded
  // whatever the polygons' shape.
  CoverageGrid(const std::vector<Polygon>& polygons, const std::vector<Eigen::Vector2d>& points,
               double margin, double resolution);

  bool Covered(double x, double y) const {
    const int64_t cx = FloorCell(x * inverse_resolution_);
    const int64_t cy = FloorCell(y * inverse_resolution_);
    const int32_t tile = directory_.Find(TileDirectory::Key(cx >> kTileBits, cy >> kTileBits));
    if (tile < 0) return false;
    return (tiles_[tile].rows[cy & kTileMask] >> (cx & kTileMask)) & 1u;
  }

  // Whether everything within deep_reach() (m) of (x, y) is covered: it lies in a wholly covered
  // tile whose eight neighbours are wholly covered too.
  bool Deep(double x, double y) const {
    const int64_t cx = FloorCell(x * inverse_resolution_);
    const int64_t cy = FloorCell(y * inverse_resolution_);
    return directory_.Find(TileDirectory::Key(cx >> kTileBits, cy >> kTileBits)) == kDeepTile;
  }
  double deep_reach() const { return 64.0 / inverse_resolution_; }

  // Share of the square [x0, x0 + side] x [y0, y0 + side] covered (16 x 16 samples).
  double CoveredShare(double x0, double y0, double side) const;
  double area() const { return area_; }            // m^2 covered
  double perimeter() const { return perimeter_; }  // m, of the covered cells (staircase)
  size_t MemoryBytes() const { return tiles_.capacity() * sizeof(Tile) + directory_.MemoryBytes(); }

 private:
  static constexpr int kTileBits = 6;
  static constexpr int64_t kTileMask = (1 << kTileBits) - 1;
  struct Tile {
    uint64_t rows[64] = {};
  };
  class Painter;

  double inverse_resolution_ = 1;
  double area_ = 0, perimeter_ = 0;
  // Wholly covered tiles share tiles_[kFullTile], or tiles_[kDeepTile] when their neighbours
  // are wholly covered too.
  static constexpr int32_t kFullTile = 0, kDeepTile = 1;
  std::vector<Tile> tiles_;
  TileDirectory directory_;
};

}  // namespace forestmap::algorithms
