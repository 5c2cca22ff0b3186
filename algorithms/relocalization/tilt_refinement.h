#pragma once
// Roll and pitch refinement from tree heights: after levelling by stem axes (about 1-2 deg off
// on real data), the matched trees' height residuals map_z - levelled_z grow linearly with
// horizontal position. A robust plane fit to them gives the residual tilt, which would otherwise
// shift every tree horizontally by its height times the tilt.

#include <optional>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct TiltRefinementOptions {
  int min_points = 12;        // matched trees with a known map height
  double min_spread = 5.0;    // m, RMS horizontal spread of those trees around their mean
  double huber_scale = 0.15;  // m, residuals beyond this are down-weighted (IRLS)
  int iterations = 6;
  double min_correction = 0.03;  // rad (~1.7 deg): smaller ones are within the height noise
  double max_correction = 0.1;   // rad (~6 deg): larger corrections are distrusted
  void Check() const;
};

// `levelled` are the matched query trees in the levelled sensor frame (x, y horizontal, z up),
// `map_z` their map trees' heights. Returns the small rotation that makes the levelled frame
// level (apply it on the left of level_from_sensor), or nullopt when the trees cannot tell or the
// tilt is already right.
std::optional<Eigen::Matrix3d> RefineTilt(const std::vector<Eigen::Vector3d>& levelled,
                                          const std::vector<double>& map_z,
                                          const TiltRefinementOptions& options = {});

}  // namespace forestmap::algorithms
