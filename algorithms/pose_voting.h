#pragma once
// Pose voting of the relocalizer (internal to algorithms/): each match of a query triangle with a
// map triangle implies a sensor pose (x, y, yaw), which votes into a pose cell.

#include <cstdint>
#include <optional>
#include <vector>

#include "algorithms/map_index_internal.h"
#include "algorithms/relocalizer.h"
#include "algorithms/rigid2d.h"

namespace forestmap::algorithms {

// A candidate pose of the levelled sensor in the map's kd coordinates.
struct Hypothesis {
  Rigid2 pose;       // kd coordinates from levelled sensor coordinates
  int votes = 0;
  int inliers = 0;
  double score = 0;  // sum over inliers of (1 - (d / inlier_distance)^2)
  double rmse = 0;
};

// One triangle match's vote: the pose it implies and the query seeds that formed it.
struct Vote {
  uint64_t cell;
  uint64_t seeds;  // bit i = seed tree i
  float yaw, x, y;
};

// Votes for sensor poses from pairs of similar query and map triangles. A pose cell is ranked by
// how many distinct query trees voted for it: near-duplicate query triangles (a stem detected
// twice, a false stem beside a true one) then cannot pile up support for a wrong pose.
class PoseVoter {
 public:
  PoseVoter(const MapIndexImpl& m, const std::vector<Eigen::Vector2d>& seed_xy,
            const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
            double tolerance)
      : m_(m), seed_xy_(seed_xy), prior_(prior), prior_xy_(prior_xy), tol_(tolerance) {
    votes_.reserve(16384);
  }

  // Adds the votes of one query triangle (its vertices index seed_xy).
  void Add(const Triangle& qt);

  // The `max` cells with the most distinct voting seeds (at least `min_votes`), each as the
  // mean pose of its votes.
  std::vector<Hypothesis> Best(int min_votes, size_t max);

 private:
  const MapIndexImpl& m_;
  const std::vector<Eigen::Vector2d>& seed_xy_;
  const std::optional<PriorPose>& prior_;
  Eigen::Vector2d prior_xy_;
  double tol_;
  std::vector<Vote> votes_;
  size_t sorted_ = 0;  // votes_[0, sorted_) are in cell order
  std::vector<std::pair<uint32_t, float>> found_;
};

}  // namespace forestmap::algorithms
