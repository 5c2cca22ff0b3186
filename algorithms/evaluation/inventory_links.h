#pragma once
// One-to-one links between detected and reference trees (inventory_comparison.h), in
// O(n log n): candidate pairs within the link distance come from a k-d tree over the reference,
// then are taken greedily by increasing distance.

#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct InventoryLink {
  int detected = 0;     // index into the detections
  int reference = 0;    // index into the reference trees
  double distance = 0;  // m, horizontal
};

// The candidate order of the greedy linking: by distance, then by detection index, then by
// reference index (so that ties give one answer whatever the input order of the search).
bool LinkBefore(const InventoryLink& a, const InventoryLink& b);

// Horizontal distance between a detection and a reference tree, m, as every linking computes it.
double LinkGap(const DetectedTree& detected, const MapTree& reference);

// Greedy by increasing distance (LinkBefore), each tree at most once; pairs farther apart than
// `distance` (m) are never linked. Returns the links in LinkBefore order.
std::vector<InventoryLink> LinkOneToOne(const std::vector<DetectedTree>& detected,
                                        const std::vector<MapTree>& reference, double distance);

}  // namespace forestmap::algorithms
