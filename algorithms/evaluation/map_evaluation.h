#pragma once
// Scoring built tree maps and trajectories against ground truth: the survey-merge bar (built
// trees vs a reference map) and the absolute trajectory error after a rigid alignment.

#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct TreeMapComparisonOptions {
  double match_distance = 0.2;      // m, a reference tree is found when a built tree is this near
  double duplicate_distance = 0.3;  // m, two built trees this near and nearest to one reference
                                    // tree (or to none) count as a duplicated stem
  void Check() const;
};

struct TreeMapComparison {
  int reference_trees = 0, built_trees = 0;
  int found = 0;                // reference trees with a built tree within match_distance
  double found_fraction = 0;    // found / reference_trees
  double distance_p50 = 0;      // m, median horizontal distance of the found pairs
  double distance_p95 = 0;      // m
  double dbh_abs_diff_p50 = 0;  // m, median |DBH difference| of found pairs with both DBHs
  int close_pairs = 0;          // built tree pairs closer than duplicate_distance
  int duplicates = 0;           // close pairs that are one stem (see options)
  int unmatched_built = 0;      // built trees with no reference tree within match_distance
};

// Horizontal comparison of a built map with a reference map (both in one frame).
TreeMapComparison CompareTreeMaps(const std::vector<MapTree>& built,
                                  const std::vector<MapTree>& reference,
                                  const TreeMapComparisonOptions& options = {});

enum class Alignment {
  kRigid,             // 3-D rotation and translation (Umeyama 1991)
  kPlanar,            // x, y, yaw and the mean height offset; horizontal errors only
  kPlanarSimilarity,  // kPlanar with a horizontal scale: the truth's scale and the sensor's
                      // can differ (Wild_V01/V02 ground truth is 0.12% larger than the stems'
                      // geometry), and a map built from the sensor alone cannot know it
};

struct TrajectoryError {
  // truth = truth_from_estimate * (scale x, scale y, z) of an estimated point (ToTruth).
  Pose3 truth_from_estimate = Pose3::Identity();
  double scale = 1;  // horizontal, kPlanarSimilarity only
  Eigen::Vector3d ToTruth(const Eigen::Vector3d& p) const {
    return truth_from_estimate * Eigen::Vector3d(scale * p.x(), scale * p.y(), p.z());
  }
  double ate_rmse = 0;  // m, RMS position error after the alignment (3-D, or 2-D if planar)
  double ate_max = 0;   // m
  double ate_p50 = 0;   // m
  int poses = 0;
};

// Least-squares alignment of estimated to true positions and the absolute trajectory error.
// `estimate` and `truth` are paired by index; fewer than 3 pairs give the identity alignment.
// Planar alignments measure the horizontal error only. Throws std::invalid_argument for
// different sizes.
TrajectoryError CompareTrajectories(const std::vector<Pose3>& estimate,
                                    const std::vector<Pose3>& truth,
                                    Alignment alignment = Alignment::kRigid);

}  // namespace forestmap::algorithms
