#pragma once
// Scoring built tree maps and trajectories against ground truth: the survey-merge bar (built
// trees vs a reference map) and the absolute trajectory error after a rigid alignment.

#include <vector>

#include "algorithms/geometry.h"

namespace forestmap::algorithms {

struct TreeMapComparisonOptions {
  double match_distance = 0.2;      // m, a reference tree is found when a built tree is this near
  double duplicate_distance = 0.3;  // m, two built trees this near and nearest to one reference
                                    // tree (or to none) count as a duplicated stem
  void Check() const;
};

struct TreeMapComparison {
  int reference_trees = 0, built_trees = 0;
  int found = 0;                 // reference trees with a built tree within match_distance
  double found_fraction = 0;     // found / reference_trees
  double distance_p50 = 0;       // m, median horizontal distance of the found pairs
  double distance_p95 = 0;       // m
  double dbh_abs_diff_p50 = 0;   // m, median |DBH difference| of found pairs with both DBHs
  int close_pairs = 0;           // built tree pairs closer than duplicate_distance
  int duplicates = 0;            // close pairs that are one stem (see options)
  int unmatched_built = 0;       // built trees with no reference tree within match_distance
};

// Horizontal comparison of a built map with a reference map (both in one frame).
TreeMapComparison CompareTreeMaps(const std::vector<MapTree>& built,
                                  const std::vector<MapTree>& reference,
                                  const TreeMapComparisonOptions& options = {});

struct TrajectoryError {
  Pose3 truth_from_estimate = Pose3::Identity();  // rigid alignment (least squares, Umeyama)
  double ate_rmse = 0;   // m, RMS position error after the alignment (3-D, or 2-D if planar)
  double ate_max = 0;    // m
  double ate_p50 = 0;    // m
  int poses = 0;
};

// Rigid (no scale) least-squares alignment of estimated to true positions (Umeyama 1991) and the
// absolute trajectory error. `estimate` and `truth` are paired by index; fewer than 3 pairs give
// the identity alignment. `planar`: align x, y and yaw (plus the mean height offset) and measure
// the horizontal error only, for tree-based mapping whose heights are weakly observed.
// Throws std::invalid_argument for different sizes.
TrajectoryError CompareTrajectories(const std::vector<Pose3>& estimate,
                                    const std::vector<Pose3>& truth, bool planar = false);

}  // namespace forestmap::algorithms
