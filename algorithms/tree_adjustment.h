#pragma once
// Planar bundle adjustment of a tree map: frame poses (x, y, yaw) and tree positions (x, y)
// jointly, from every detection's association, by Gauss-Newton with the trees eliminated (Schur
// complement, each tree a 2x2 block) and a sparse Cholesky of the reduced pose system. Used by
// the map builder after the incremental pass: the incremental map fixes a tree where it was first
// seen, the joint solution lets all observations pull together (less drift between loops).

#include <vector>

#include "algorithms/pose_graph.h"

namespace forestmap::algorithms {

struct TreeAdjustmentObservation {
  int frame = 0;                                     // index into the poses
  int tree = 0;                                      // index into the trees
  Eigen::Vector2d level_xy = Eigen::Vector2d::Zero();  // m, levelled sensor frame
  double weight = 1;                                 // 1/m^2
};

struct TreeAdjustmentOptions {
  int iterations = 8;
  double huber = 0.3;  // m, residuals beyond this are down-weighted (wrong associations)
  int max_tree_observations = 40;  // per tree, an even subset beyond this (cost is O(n^2))
  void Check() const;
};

struct TreeAdjustmentResult {
  std::vector<Pose4> poses;                // z unchanged
  std::vector<Eigen::Vector2d> trees;
  double initial_rms = 0, final_rms = 0;   // m, weighted residual RMS
  int iterations = 0;
};

// `trees` are initial positions; frame 0 is held fixed. Trees with fewer than 2 observations
// take no part (they are returned moved with their frame). Throws std::invalid_argument for an
// observation naming a frame or tree out of range.
TreeAdjustmentResult AdjustTrees(std::vector<Pose4> poses, std::vector<Eigen::Vector2d> trees,
                                 const std::vector<TreeAdjustmentObservation>& observations,
                                 const TreeAdjustmentOptions& options = {});

}  // namespace forestmap::algorithms
