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

// A query tree's share of the looked-up triangles: when a query has more than the search looks
// up, the nearest ones are taken but none of its trees is a vertex of more than this many of
// them before every tree has had its turn. A false stem near the sensor (a dense stand's views
// hold 20% and more) is a vertex of most of the nearest triangles: nearest-first alone filled
// whole searches with its triangles and never tried one of three true trees.
inline constexpr int kMaxTrianglesPerSeed = 16;

// Keeps at most `max` of `triangles` (nearest first, as QueryTriangles orders them): first, in
// order, those whose vertices are each in fewer than `per_seed` triangles kept so far, then, in
// order, the others until `max`; the kept ones stay in their order.
void KeepSpread(std::vector<QueryTriangle>& triangles, size_t max, int per_seed);

}  // namespace forestmap::algorithms
