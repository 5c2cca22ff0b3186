#pragma once
// The immutable per-map search structure of the relocalizer.

#include <cmath>
#include <memory>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/polygon.h"
#include "algorithms/relocalization/coverage.h"

namespace forestmap::algorithms {

struct MapIndexOptions {
  // Triangle keys (triangle_levels.h): a tree's triangles use sides up to the length at which
  // it has this many neighbours (from its local spacing), on levels of sides growing by
  // level_ratio; more = more robust, bigger index.
  double target_neighbours = 10.0;
  double level_ratio = M_SQRT2;
  double spacing_cell = 25.0;  // m, local spacing is the median over cells this wide
  // A drone sees fewer trees than a dense map holds (occlusion, misses): its triangles need at
  // least this side length to exist at all (the lowest level). Bounded by the budget below.
  double min_triangle_side = 3.5;  // m
  // Index size bound (16 bytes a triangle): tight for huge maps, generous for small ones.
  double max_triangles_per_tree = 8.0;           // maps of more than large_map_trees trees
  double small_map_triangles_per_tree = 1000.0;  // smaller maps
  size_t large_map_trees = 200000;
  // Where the local spacing (triangle_levels.h) exceeds sparse_spacing, the per-tree budget
  // grows as (spacing / sparse_spacing)^2, by at most sparse_budget_factor (triangle_levels.h
  // SparseBudget): a view in a sparse stand sees few trees and needs more triangles of each.
  double sparse_spacing = 4.0;        // m (0: no growth)
  double sparse_budget_factor = 2.5;  // times the per-tree budget, at most
  // Small or sparse maps: grow the sides until the index holds this many triangles (2.4 MB), so
  // that the few trees a sensor sees in a sparse forest, tens of metres apart, still form
  // indexed triangles; the search stays cheap on a small index.
  double min_index_triangles = 150000;
  double max_triangle_side = 30.0;  // m, at most 32 (the table's key range)
  // The occupancy grid that rejects wrong poses quickly: cells within this radius of a tree
  // (about the relocalizer's inlier distance), at this resolution.
  double occupancy_radius = 0.4;      // m
  double occupancy_resolution = 0.2;  // m
  int threads = 0;  // index build threads for large maps; 0 = hardware concurrency
  // What the map covers when no survey boundary is given: derived from the trees (coverage.h).
  CoverageOptions coverage;
  void Check() const;
};

class MapIndexImpl;

// Tree coordinates the index accepts (m, |x|, |y| and a known |z|); beyond it, or not finite,
// the constructor throws std::invalid_argument naming the tree.
inline constexpr double kMaxIndexCoordinate = 1e9;

// The immutable per-map search structure, built once per map version, with what the map covers
// (coverage.h): its survey boundary (polygons with holes, map frame) when given, else the
// coverage its trees say it has. Thread-safe for concurrent queries.
class MapIndex {
 public:
  // Throws std::invalid_argument for invalid options, a tree beyond kMaxIndexCoordinate or an
  // invalid boundary polygon.
  MapIndex(std::vector<MapTree> trees, const MapIndexOptions& options = {},
           std::vector<Polygon> boundary = {});
  ~MapIndex();
  MapIndex(const MapIndex&) = delete;
  MapIndex& operator=(const MapIndex&) = delete;

  size_t size() const;
  const std::vector<MapTree>& trees() const;
  bool has_z() const;            // every tree has a z
  bool has_dbh() const;          // most trees have a DBH
  size_t MemoryBytes() const;    // approximate resident size of the index
  double triangle_side() const;  // m, longest triangle side indexed (in the sparsest level)
  size_t triangle_count() const;
  // Triangles of each level (triangle_levels.h) and their longest side (m).
  std::vector<std::pair<double, size_t>> triangle_levels() const;
  // The boundary given, else the coverage derived from the trees (map frame), and its area (m^2,
  // of its raster).
  const std::vector<Polygon>& coverage() const;
  // Whether the map covers `map_xy` (map frame, m): its rasterized coverage, in nanoseconds.
  bool Covers(const Eigen::Vector2d& map_xy) const;
  bool coverage_derived() const;
  double coverage_area() const;
  const MapIndexImpl& impl() const { return *impl_; }

 private:
  std::unique_ptr<MapIndexImpl> impl_;
};

// The coverage a MapIndex of `trees` derives when given no boundary (coverage.h), map frame: what
// one map of many brings to an index over their union when others bring survey boundaries.
// Throws what the MapIndex constructor throws for the trees.
std::vector<Polygon> DerivedCoverage(const std::vector<MapTree>& trees,
                                     const MapIndexOptions& options = {});

}  // namespace forestmap::algorithms
