#pragma once
// Helpers shared by map_merge.cc and map_consolidate.cc; not part of the public API.

#include <memory>
#include <span>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/merging/map_merge.h"

namespace forestmap::algorithms::internal {

// The canonical order of rows: frame number, source, detection index, tree id (frame number
// first: when the uploads of several drones number their frames along one sequence, the order,
// and so the map, does not depend on how the sources are named or split).
bool CanonicalLess(const TreeObservation& a, const TreeObservation& b);

// Re-derives a tree's position, DBH, sigmas, view count and status from its statistics.
void Finalize(TreeEstimate& tree, const MergeOptions& options);

struct PairCost {
  double cost = -1;     // squared Mahalanobis distance + DBH term; < 0 when gated out
  bool dbh_ok = true;   // false: the DBHs disagree beyond the DBH gate
  double distance = 0;  // m, horizontal
};
PairCost AssociationCost(const TreeEstimate& tree, const TreeObservation& observation,
                         const MergeOptions& options);

struct Association {
  std::vector<int> tree;  // per observation: tree index, or -1
};

// One-to-one greedy association of one frame's observations with trees, cheapest pair first
// (ties by tree id). DBH-compatible pairs first; then observations within
// dbh_outlier_distance of a still free tree join it despite their DBH (and their DBH is
// averaged with its weight: a stored row never changes, or the map would depend on the order
// in which rows arrived).
Association AssociateGreedy(std::span<const TreeEstimate> trees,
                            std::span<const TreeObservation> observations,
                            const MergeOptions& options);
// As above with a prebuilt k-d tree over the trees' xy (same order).
Association AssociateGreedy(std::span<const TreeEstimate> trees, const KdTree<double, 2>& trees_xy,
                            std::span<const TreeObservation> observations,
                            const MergeOptions& options);

// A k-d tree over the trees' horizontal positions.
std::unique_ptr<KdTree<double, 2>> BuildTreeIndex(std::span<const TreeEstimate> trees);

}  // namespace forestmap::algorithms::internal
