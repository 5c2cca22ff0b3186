#pragma once
// Connected components of observation rows (map_merge.h): two rows whose horizontal positions
// are closer than a link distance (MergeOptions::gate_distance) are linked, and a component is
// everything linked directly or through other rows. A row can join a tree only within
// gate_distance of the tree's mean, which lies among the tree's rows, so a component's rows
// never have reason to join another component's trees: RebuildTrees merges each component on
// its own, and the map is the union of its components' trees.
//
// Thread-safety: ObservationLinker is a value type without shared state.

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "algorithms/merging/map_merge.h"

namespace forestmap::algorithms {

// Components built incrementally: points may be added in any order and at any time; which
// points end up linked does not depend on the order (union-find over a hash grid of cells as
// large as the link distance, so only the 3 x 3 cells around a point hold its neighbours).
class ObservationLinker {
 public:
  // Throws std::invalid_argument for a link distance that is not finite and > 0.
  explicit ObservationLinker(double link_distance);

  // Adds a point (map frame, m) and links it with every earlier point closer than the link
  // distance (<=, the same test for every pair). Returns its index (0, 1, ...).
  int Add(const Eigen::Vector2d& xy);

  // Links two points whatever their distance (a caller's own reason to keep them together).
  void Link(int a, int b);

  // The component of point `index`: equal for two points exactly when they are linked. The
  // value may change when later points join components.
  int Root(int index);

  size_t size() const { return xy_.size(); }

 private:
  static int64_t Key(int64_t cx, int64_t cy) { return (cx << 32) ^ (cy & 0xffffffffLL); }

  double link_distance_;
  std::vector<Eigen::Vector2d> xy_;
  std::vector<int> parent_;
  std::unordered_map<int64_t, std::vector<int>> cells_;
};

// The component of each row, numbered 0, 1, ... in the order of each component's first row;
// the link distance is options.gate_distance.
std::vector<int> ObservationComponents(std::span<const TreeObservation> observations,
                                       const MergeOptions& options = {});

}  // namespace forestmap::algorithms
