#pragma once
// Landmark bundle adjustment of a tree map: every frame's pose (x, y, z, yaw of the levelled
// sensor; roll and pitch come from levelling) and every tree's position (x, y, z) jointly, from
// each detection's association, by Gauss-Newton (Levenberg-Marquardt damped) with the trees
// eliminated (Schur complement, one 3x3 diagonal block per tree) and a sparse Cholesky
// (SimplicialLDLT) of the reduced pose system. Observations are robust (Huber, optionally then
// Cauchy), so wrong associations pull with a bounded force. Optional relative-pose edges (odometry)
// tie frames. Used by the map builder after the incremental pass: the incremental map fixes a tree
// where it was first seen, the joint solution lets all observations (loop closures included) pull
// together.
//
// A frame's height here is its APPARENT height: where its detected stems put it. Real detections
// are off in height by metres for stretches of frames (Wild_V01: 8 frames at up to 12 m), all
// stems of a frame alike; a free apparent height absorbs that, so the trees' heights stay clean,
// and SmoothHeights then tells the sensor's height from the apparent ones.

#include <vector>

#include "algorithms/mapping/pose_graph.h"

namespace forestmap::algorithms {

struct TreeAdjustmentObservation {
  int frame = 0;                                             // index into the poses
  int tree = 0;                                              // index into the trees
  Eigen::Vector3d level_position = Eigen::Vector3d::Zero();  // m, levelled sensor frame
  double weight_xy = 1;                                      // 1/m^2, per horizontal axis
  double weight_z = 0;  // 1/m^2; 0 = height not used (unknown or unreliable)
};

struct TreeAdjustmentOptions {
  int iterations = 15;             // Gauss-Newton steps in all (Huber, then Cauchy)
  double huber_xy = 2.0;           // m, Huber threshold of horizontal residuals
  int cauchy_iterations = 0;       // of `iterations`, Cauchy steps after the Huber steps
  double cauchy_xy = 0.15;         // m, Cauchy scale of horizontal residuals
  double cauchy_z = 0.4;           // m, Cauchy scale of height residuals
  double tolerance = 1e-6;         // relative cost decrease that ends the iterations
  int max_tree_observations = 40;  // per tree, an even subset beyond this (cost is O(n^2))
  void Check() const;              // throws std::invalid_argument naming the field
};

struct TreeAdjustmentResult {
  std::vector<Pose4> poses;
  std::vector<Eigen::Vector3d> trees;       // z NaN for trees without a height observation
  double initial_rms = 0, final_rms = 0;    // m, weighted horizontal residual RMS
  double initial_cost = 0, final_cost = 0;  // robust cost (Huber)
  int iterations = 0;
};

// `trees` are initial positions; frame 0 is held fixed. Trees with fewer than 2 observations
// do not move the poses (they follow their frame). `edges` (pose_graph.h, non-robust) add
// relative-pose terms between frames. Throws std::invalid_argument for an observation or edge
// naming a frame or tree out of range, or invalid options.
TreeAdjustmentResult AdjustTrees(std::vector<Pose4> poses, std::vector<Eigen::Vector3d> trees,
                                 const std::vector<TreeAdjustmentObservation>& observations,
                                 const std::vector<PoseGraphEdge>& edges = {},
                                 const TreeAdjustmentOptions& options = {});

// Sensor heights from apparent heights (NaN = none): the z minimising
// sum rho(z_i - apparent_i) + sum ((z_i - z_{i-1}) / step_sigma)^2 with a Cauchy rho of scale
// `outlier_scale` (m), by iteratively reweighted least squares from a running median. A stretch
// of frames whose stems are all off by metres then leaves the sensor's height alone.
std::vector<double> SmoothHeights(const std::vector<double>& apparent, double step_sigma,
                                  double outlier_scale, int iterations = 20);

}  // namespace forestmap::algorithms
