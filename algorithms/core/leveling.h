#pragma once
// Levelling of a tilted sensor frame: the rotation that makes the sensor's "up" the z axis.

#include <optional>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct LevelingOptions {
  double axis_inlier_angle = 0.26;  // rad (~15 deg), stem axes farther from the mean are outliers
  int min_axes = 3;                 // fewer usable stem axes -> assume a level sensor
  void Check() const;
};

enum class LevelSource { kGravity, kStemAxes, kAssumedLevel };

struct LevelingResult {
  Eigen::Matrix3d level_from_sensor = Eigen::Matrix3d::Identity();  // rotation, no yaw change
  LevelSource source = LevelSource::kAssumedLevel;
  int axes_used = 0;
};

// Up direction from `gravity` (down, sensor frame) when given; else the robust mean of the
// stems' axes (sign-free: principal direction of sum a a^T, signed so that stem points lie below
// the sensor, as for a drone or a handheld scanner); else identity. The returned rotation is the
// minimal one taking "up" to +z, so the sensor's heading is kept.
LevelingResult LevelSensor(const std::vector<DetectedTree>& trees,
                           const std::optional<Eigen::Vector3d>& gravity,
                           const LevelingOptions& options = {});

}  // namespace forestmap::algorithms
