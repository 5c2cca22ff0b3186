#pragma once
// Internal to the relocalizer: the query's triangles and the bands of the map's triangle tables
// (triangle_levels.h) they are looked up in.

#include <utility>
#include <vector>

#include "algorithms/relocalization/map_index_internal.h"

namespace forestmap::algorithms {

// A query triangle and the band (triangle_levels.h) whose table it is looked up in.
struct QueryTriangle {
  Triangle triangle;
  int level = 0;
};

// The longest side a query's triangles may have: that of the level below the one its own
// spacing suggests (a drone misses trees, so it sees a wider spacing than the map's), within
// the levels the map holds triangles of.
double QuerySide(const std::vector<Eigen::Vector2d>& seed_xy, const MapIndexImpl& m);

// Query triangles among the seeds (the nearest query trees) with sides up to `max_side` (m),
// widened by the matching tolerance, nearest first (by their farthest vertex); each with the
// bands its longest side may fall in on the map.
std::vector<QueryTriangle> QueryTriangles(const std::vector<Eigen::Vector2d>& seed_xy,
                                          const MapIndexImpl& m, double max_side, double tolerance);

}  // namespace forestmap::algorithms
