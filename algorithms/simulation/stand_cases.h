#pragma once
// Synthetic stands for relocalization benchmarks across a forest district (simulation.h has
// natural forests): planted stands on a regular grid, and mosaics tiled from real stem maps of
// very different densities. Deterministic given the seeds.

#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct PlantationOptions {
  double spacing_x = 4.0;       // m, between rows
  double spacing_y = 4.0;       // m, between trees along a row
  double planting_error = 0.2;  // m, sd per axis of a tree's offset from its grid point
  double mortality = 0.1;       // [0, 1), share of the grid points without a tree
  double width = 200;           // m, extent along x, from x = 0
  double height = 200;          // m, extent along y, from y = 0
  double dbh_mean = 0.2;        // m, DBH is log-normal with this median ...
  double dbh_log_sd = 0.2;      // ln(m), ... and this sd of ln(DBH) (even-aged: small)
  unsigned seed = 1;
  void Check() const;  // throws std::invalid_argument naming the field
};

// A plantation: a tree at every grid point (spacing_x / 2 + i spacing_x, spacing_y / 2 +
// j spacing_y) but the dead ones, moved by the planting error. Ids 0..n-1, z unknown.
std::vector<MapTree> GeneratePlantation(const PlantationOptions& options);

struct MosaicOptions {
  size_t trees = 1000000;  // stop adding tiles once the mosaic holds this many trees
  double tile = 315;       // m, pitch of the square tile grid (>= each map's diagonal)
  double jitter = 1.0;     // m, sd per axis of the offset added to every tree
  double thinning = 0.15;  // [0, 1), share of each tile's trees dropped at random
  unsigned seed = 1;
  void Check() const;  // throws std::invalid_argument naming the field
};

// A district: tiles on a square grid (row by row, about as many columns as rows), each a copy
// of one of `stands` drawn at random, centred in its tile, rotated by a random angle, thinned,
// every tree moved by the jitter (no two tiles alike). Ids 0..n-1; z and DBH as in the stand.
// Throws std::invalid_argument when a stand is empty or does not fit in a tile.
std::vector<MapTree> TileMosaic(const std::vector<std::vector<MapTree>>& stands,
                                const MosaicOptions& options);

}  // namespace forestmap::algorithms
