#pragma once
// Ground segmentation by pillars and a ground height model, so that every point gets a height
// above ground, on slopes too.
//
// Pillars (Zmeškalová 2023, sec. 2.3, after Bartek 2022): a 2-D grid of square pillars; the points
// within `candidate_height` of a pillar's lowest point are ground candidates. Unlike Zmeškalová, a
// candidate only counts if its fine sub-cell holds no vertical structure (the foot of a stem, a
// trunk slice without any ground): ground is thin in z at a fixed x, y, a stem is not. Pillars
// whose ground lies implausibly high above their neighbours' (a shrub top where the ground is
// hidden) are dropped. The height model follows the backpack paper (Holmgren et al. 2017,
// sec. 2.5): each pillar centre gets a height from the ground samples around it (a local
// least-squares plane when the samples span one, else inverse squared distance weighting), pillars
// without samples get it from the nearest window of pillars that has some; a point's ground height
// is the bilinear interpolation of the pillar centres' heights.
//
// With too few ground pillars (a cloud of trunk slices) the ground is unknown: heights are then
// relative to the lowest point of the cloud and `known()` is false. For one scan from a sensor at
// the origin (sensor_at_origin), samples that lie above a beam that passed over them are dropped
// (free space: the ground is below that beam), and the height model falls back to one plane
// through all the ground seen where no ground is within fill_radius.

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct GroundOptions {
  double cell_size = 1.0;            // m, pillar side (Zmeškalová 2023: 1.8 m)
  double candidate_height = 0.3;     // m, above a pillar's lowest point (Zmeškalová 2023: 0.45 m)
  double subcell_size = 0.1;         // m, resolution of the vertical-structure test
  double max_subcell_extent = 0.12;  // m, candidates of one sub-cell spanning more are not ground
  int min_cell_points = 3;           // ground samples for a pillar to hold ground
  double min_ground_share = 0.5;     // ... and at least this share of its candidates
  double max_step = 0.3;             // m, a pillar's ground above its neighbours' by more, plus
  double max_slope = 0.5;            // (rise/run) times their distance, is an outlier
  int min_ground_cells = 4;          // fewer ground pillars: the ground is unknown
  int fill_radius = 10;              // pillars, search window for pillars without ground samples
  double label_height = 0.15;        // m, points lower than this above the model are "ground"
  size_t max_grid_cells = 4'000'000;  // larger extents use proportionally larger pillars
  // One scan from a sensor at the origin (DetectTrunks sets it with StemModelOptions::
  // sensor_at_origin): a beam that passed over a pillar to a farther return tells that the ground
  // there lies below it. A drone's narrow field of view sees no ground near it (an OS1 at 10 m
  // sees ground from 24 m on); there the lowest things seen (shrub tops, the lowest stem ring)
  // lie above its lowest beams and are no ground: such samples are dropped, and pillars without
  // ground within fill_radius take it from a plane through all the ground seen.
  bool sensor_at_origin = false;
  void Check() const;
};

// Ground height over a grid in the cloud's frame; a cheap value type, queried per point.
class GroundModel {
 public:
  GroundModel() = default;
  GroundModel(double min_x, double min_y, double cell, int nx, int ny, std::vector<float> heights);

  bool known() const { return !heights_.empty(); }
  // Ground z at (x, y), m; NaN when unknown or outside the filled grid.
  double Height(double x, double y) const;
  double cell_size() const { return cell_; }

 private:
  double min_x_ = 0, min_y_ = 0, cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<float> heights_;  // at pillar centres, row-major (y major); NaN = no value
};

struct GroundSegmentation {
  GroundModel model;
  bool ground_known = false;
  std::vector<float> height;       // per point: m above ground (or above the lowest point)
  std::vector<uint8_t> is_ground;  // per point
  size_t ground_points = 0;
  int ground_cells = 0;           // pillars holding ground samples after outlier removal
  double reference_z = kUnknown;  // ground unknown: the z heights are relative to
};

GroundSegmentation SegmentGround(std::span<const Eigen::Vector3f> points,
                                 const GroundOptions& options);

}  // namespace forestmap::algorithms
