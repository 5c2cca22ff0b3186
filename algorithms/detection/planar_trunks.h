#pragma once
// Trunks in one revolution of a planar (2-D) LiDAR, after Park & Park 2023 (sec. 2.2-2.3,
// "tree detection"): keep returns within a range and field of view, group
// consecutive returns whose ranges do not jump, keep groups no wider than a trunk, keep the points
// near the group's median point (separates overlapping trunks at similar ranges), then a Kasa
// circle fit (refined geometrically) only on groups with enough points (short arcs of far trunks
// give wild circles).

#include <cstdint>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/point_cloud.h"
#include "algorithms/detection/circle_fit.h"

namespace forestmap::algorithms {

struct PlanarTrunkOptions {
  double min_range = 0.1;            // m
  double max_range = 10.0;           // m (paper: 5 m)
  double fov_center = 0;             // rad, direction of the field of view's centre
  double fov_width = 2 * M_PI;       // rad, full width (paper: 100 deg)
  double range_jump = 0.1;           // m, consecutive returns further apart in range split a group
  double range_jump_ratio = 0.03;    // ... or by this share of the range, if larger
  int max_gap_beams = 2;             // missing returns tolerated inside one group
  double max_width = 0.55;           // m, end-to-end width of a trunk group (paper: 0.55 m)
  double median_radius = 0.5;        // m, points farther from the group's median point are dropped
  int min_points = 8;                // points for a circle fit (paper: 40 at 0.12 deg resolution)
  double min_radius = 0.025;         // m
  double max_radius = 0.6;           // m
  double max_rms = 0.02;             // m, geometric residual of the fit
  bool geometric_refinement = true;  // Levenberg-Marquardt after Kasa
  void Check() const;
};

struct PlanarTrunk {
  DetectedTree tree;  // position = circle centre (z = 0), dbh = 2 r, axis = +z
  Circle circle;
  int points = 0;                     // points of the fit
  double rms = 0;                     // m
  int first_beam = 0, last_beam = 0;  // beam range of the group
};

struct PlanarTrunkResult {
  std::vector<PlanarTrunk> trunks;  // in beam order
  size_t returns_kept = 0;          // after the range / field-of-view filter
  size_t groups = 0;
  size_t rejected_width = 0;
  size_t rejected_points = 0;  // too few points after the median filter
  size_t rejected_fit = 0;     // no fit, radius out of bounds, residual, or concave arc
};

PlanarTrunkResult DetectPlanarTrunks(const PlanarScan& scan, const PlanarTrunkOptions& options);

}  // namespace forestmap::algorithms
