#pragma once
// Coordinates and cells of the observation cell index tests (storage::ObservationCell), shared
// by the test on every backend and the test of SQLite's migration that made the index.

#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage {

// Coordinates on both sides of cell edges (multiples of kObservationCellSize), around 0 and
// far out, in both signs.
inline std::vector<double> Coordinates() {
  const double s = kObservationCellSize;
  return {-2 * s - 1e-9, -2 * s,   -s, -s + 1e-12,   -1e-300,   0.0,       1e-12,
          0.5 * s,       s - 1e-9, s,  3 * s + 0.25, 1e6 + 0.1, -1e6 - 0.1};
}

// The cells of the first column of rows and of both diagonals, and two around the origin.
inline std::vector<ObservationCell> SomeCells() {
  std::vector<ObservationCell> cells;
  for (const double x : Coordinates()) {
    cells.push_back(CellOf(Coordinates().front(), x));
    cells.push_back(CellOf(x, x));
    cells.push_back(CellOf(x, -x));
  }
  cells.push_back({-1, 0});
  cells.push_back({0, -1});
  return cells;
}

}  // namespace forestmap::storage
