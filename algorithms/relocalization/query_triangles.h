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

// A query tree's share of the looked-up triangles. The search looks triangles up nearest first
// and stops after a budget (max_query_triangles, max_scored_hypotheses): a false stem near the
// sensor (dense stands' views hold 20% and more, clustered near it by chance) is a vertex of
// most of the nearest triangles, and nearest-first alone spent whole searches on its triangles
// without ever trying one of three true trees. So the order goes in rounds: nearest first, but
// no tree a vertex of more than kFirstTrianglesPerSeed triangles in the first round, twice that
// in the next, up to kMaxTrianglesPerSeed; then the rest, nearest first.
inline constexpr int kFirstTrianglesPerSeed = 4;
inline constexpr int kMaxTrianglesPerSeed = 16;

// Reorders `triangles` (nearest first, as QueryTriangles orders them) in those rounds: round k
// takes, in order, the triangles not yet taken whose vertices are each in fewer than
// min(first_per_seed x 2^k, per_seed) triangles taken so far; after the round at per_seed, the
// rest in order. Keeps the first `max`.
void KeepSpread(std::vector<QueryTriangle>& triangles, size_t max, int first_per_seed,
                int per_seed);

}  // namespace forestmap::algorithms
