#pragma once
// Uncertainty of a relocalized pose: 6 x 6 covariance of (x, y, z, roll, pitch, yaw) in the map
// frame (m, rad about the map's fixed axes; ROS geometry_msgs/PoseWithCovariance order).
//
// x, y, yaw: the least-squares information of the matched tree pairs (each pair constrains the
// position, and the heading through its lever arm), with the per-axis residual variance
// estimated from the pairs themselves (floored: a handful of near-perfect matches do not make a
// centimetre pose; scaled for the few degrees of freedom of a small set) and inflated because
// neighbouring trees' errors are correlated (shared occlusion), not independent; plus the map's
// own error against the world (survey drift, shared by neighbouring trees), from the residual
// variance in excess of a frame's detection noise. z: the spread of the matched trees' height
// offsets (the median's variance); unknown (kUnknownVariance) for a map without heights. roll,
// pitch: the levelling's typical error (stem axes or gravity), not estimated per query.

#include <Eigen/Core>
#include <vector>

namespace forestmap::algorithms {

struct PoseCovarianceInput {
  std::vector<Eigen::Vector2d> sensor_xy;  // matched query trees, levelled sensor frame (m)
  std::vector<Eigen::Vector2d> residual;   // map tree - posed query tree, per pair (m)
  std::vector<double> dz;                  // map z - query z per pair with a map height (m)
  double yaw = 0;                          // rad, the pose's heading
};

inline constexpr double kUnknownVariance = 1e6;  // m^2 or rad^2: the component is not observed

Eigen::Matrix<double, 6, 6> PoseCovariance(const PoseCovarianceInput& input);

}  // namespace forestmap::algorithms
