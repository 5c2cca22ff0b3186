#pragma once
// Geometry types of ForestMap.
//
// Axes and units, stated once: metres and radians; right-handed frames. The MAP frame has z up
// (against gravity). The SENSOR frame is whatever the LiDAR reports in, possibly tilted.
// A transform named `a_from_b` maps points in frame b to frame a: p_a = a_from_b * p_b.
// Unknown scalar values (a 2-D survey's z, a missing DBH) are NaN.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace forestmap::algorithms {

inline constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

inline bool IsKnown(double v) { return !std::isnan(v); }

using Pose3 = Eigen::Isometry3d;

// A tree of a map, in the map frame.
struct MapTree {
  int64_t id = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m; z is NaN for 2-D surveys
  double dbh = kUnknown;                               // m
};

// A tree detected in one scan, in the sensor frame.
struct DetectedTree {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // m, a point on the stem axis
  double dbh = kUnknown;                               // m
  Eigen::Vector3d axis = Eigen::Vector3d::Zero();      // unit stem direction; zero = unknown
  double score = kUnknown;                             // fit quality in [0, 1]

  bool HasAxis() const { return axis.squaredNorm() > 0.25; }
};

// Yaw (rotation about map z) of a rotation, in radians.
inline double YawOf(const Eigen::Matrix3d& rotation) {
  return std::atan2(rotation(1, 0), rotation(0, 0));
}

// Pose with only yaw about z plus a translation.
inline Pose3 PoseFromXyzYaw(double x, double y, double z, double yaw) {
  Pose3 pose = Pose3::Identity();
  pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, y, z);
  return pose;
}

// Wraps an angle (rad) to (-pi, pi]: pi stays pi, -pi becomes pi.
inline double WrapAngle(double a) {
  a = std::fmod(a + M_PI, 2.0 * M_PI);  // (-2 pi, 2 pi)
  if (a <= 0) a += 2.0 * M_PI;          // (0, 2 pi]
  return a - M_PI;
}

}  // namespace forestmap::algorithms
