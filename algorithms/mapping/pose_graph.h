#pragma once
// A small 4-DoF pose graph (x, y, z, yaw: roll and pitch come from levelling and do not drift)
// solved by Gauss-Newton with a sparse Cholesky factorisation (Eigen SimplicialLDLT), for loop
// closure in the map builder. Edges are relative poses with per-axis sigmas and an optional
// Huber kernel (a wrong loop closure then pulls with a bounded force).

#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct Pose4 {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // m, map frame
  double yaw = 0;                                         // rad about map z
};

// Pose of `b` in the frame of `a` (x, y rotated into a's heading; z and yaw as differences).
Pose4 Between(const Pose4& a, const Pose4& b);
// The pose b = a (+) relative.
Pose4 Compose(const Pose4& a, const Pose4& relative);

struct PoseGraphEdge {
  int from = 0, to = 0;  // node indices
  Pose4 measurement;     // Between(node from, node to) as measured
  Eigen::Vector4d sigma = Eigen::Vector4d(0.05, 0.05, 0.05, 0.005);  // m, m, m, rad
  bool robust = false;  // Huber kernel on this edge (loop closures)
};

struct PoseGraphOptions {
  int max_iterations = 30;
  double tolerance = 1e-6;  // relative cost decrease that ends the iterations
  double huber = 3.0;       // sigmas, Huber threshold of robust edges
  void Check() const;
};

struct PoseGraphResult {
  std::vector<Pose4> poses;
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;  // sum of squared (weighted) residuals
};

// One edge linearised at (a, b): whitened residual (Between(a, b) - measurement, per axis
// x, y, z, yaw over its sigma) and its Jacobians w.r.t. the two nodes (x, y, z, yaw), whitened.
struct LinearizedEdge {
  Eigen::Vector4d residual;
  Eigen::Matrix4d jacobian_from, jacobian_to;
};
LinearizedEdge LinearizeEdge(const Pose4& a, const Pose4& b, const PoseGraphEdge& edge);

// Optimises all nodes but `fixed_node`. Throws std::invalid_argument for an edge naming a node
// out of range, a non-positive sigma or invalid options.
PoseGraphResult OptimizePoseGraph(std::vector<Pose4> initial,
                                  const std::vector<PoseGraphEdge>& edges, int fixed_node = 0,
                                  const PoseGraphOptions& options = {});

}  // namespace forestmap::algorithms
