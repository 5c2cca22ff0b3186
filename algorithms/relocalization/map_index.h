#pragma once
// The immutable per-map search structure of the relocalizer.

#include <memory>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct MapIndexOptions {
  // Triangle keys use sides up to the length at which a tree has this many neighbours on
  // average (from the map's nearest-neighbour statistics); more = more robust, bigger index.
  double target_neighbours = 6.0;
  // A drone sees fewer trees than a dense map holds (occlusion, misses): its triangles need at
  // least this side length to exist at all. Bounded by the triangle budget below.
  double min_triangle_side = 3.5;  // m
  // Index size bound (20 bytes a triangle): tight for huge maps, generous for small ones.
  double max_triangles_per_tree = 12.0;          // maps of more than large_map_trees trees
  double small_map_triangles_per_tree = 1000.0;  // smaller maps
  size_t large_map_trees = 200000;
  // Small or sparse maps: grow the side until the index holds this many triangles (3 MB), so
  // that the few trees a sensor sees in a sparse forest, tens of metres apart, still form
  // indexed triangles; the search stays cheap on a small index.
  double min_index_triangles = 150000;
  double max_triangle_side = 30.0;  // m
  // The occupancy grid that rejects wrong poses quickly: cells within this radius of a tree
  // (about the relocalizer's inlier distance), at this resolution.
  double occupancy_radius = 0.4;      // m
  double occupancy_resolution = 0.2;  // m
  int threads = 0;  // index build threads for large maps; 0 = hardware concurrency
  void Check() const;
};

class MapIndexImpl;

// Tree coordinates the index accepts (m, |x|, |y| and a known |z|); beyond it, or not finite,
// the constructor throws std::invalid_argument naming the tree.
inline constexpr double kMaxIndexCoordinate = 1e9;

// The immutable per-map search structure, built once per map version. Thread-safe for
// concurrent queries.
class MapIndex {
 public:
  // Throws std::invalid_argument for invalid options or a tree beyond kMaxIndexCoordinate.
  MapIndex(std::vector<MapTree> trees, const MapIndexOptions& options = {});
  ~MapIndex();
  MapIndex(const MapIndex&) = delete;
  MapIndex& operator=(const MapIndex&) = delete;

  size_t size() const;
  const std::vector<MapTree>& trees() const;
  bool has_z() const;            // every tree has a z
  bool has_dbh() const;          // most trees have a DBH
  size_t MemoryBytes() const;    // approximate resident size of the index
  double triangle_side() const;  // m, longest triangle side indexed
  size_t triangle_count() const;
  const MapIndexImpl& impl() const { return *impl_; }

 private:
  std::unique_ptr<MapIndexImpl> impl_;
};

}  // namespace forestmap::algorithms
