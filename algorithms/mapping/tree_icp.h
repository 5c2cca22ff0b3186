#pragma once
// Tree-to-tree ICP in the plane (x, y, yaw; z from the matched heights) of a levelled frame
// against map trees, for the map builder: nearest map tree within a shrinking gate, one map
// tree per query tree (closest wins), weighted closed-form 2-D Procrustes per iteration.

#include <utility>
#include <vector>

#include "algorithms/core/kdtree.h"
#include "algorithms/mapping/pose_graph.h"

namespace forestmap::algorithms {

struct TreeIcpResult {
  Pose4 map_from_level;                      // refined pose
  int inliers = 0;                           // matches within the last gate
  double rmse = 0;                           // m, horizontal
  std::vector<std::pair<int, int>> matches;  // (query index, map index)
};

// `query` in the levelled sensor frame (z up), `map` in the map frame with `map_xy` its k-d tree
// (same order). Gates in m, used in turn for `iterations` rounds each; the first gate from 7
// headings within +-yaw_search (rad) of the initial one. `map_variances` (m^2 per map tree,
// optional) lower the weight of uncertain map trees.
TreeIcpResult TreeIcp(const std::vector<Eigen::Vector3d>& query,
                      const std::vector<double>& query_weights,
                      const std::vector<Eigen::Vector3d>& map, const KdTree<double, 2>& map_xy,
                      const Pose4& initial, const std::vector<double>& gates, int iterations,
                      double yaw_search = 0.45, const std::vector<double>& map_variances = {});

// A Pose3 with the translation and yaw of `pose` (no roll or pitch).
Pose3 ToPose3(const Pose4& pose);
// Translation and yaw of a (levelled) Pose3.
Pose4 ToPose4(const Pose3& pose);

}  // namespace forestmap::algorithms
