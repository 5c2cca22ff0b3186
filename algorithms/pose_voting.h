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

// Votes for sensor poses from pairs of similar query and map triangles. A pose cell is ranked by
// how many distinct query trees voted for it: near-duplicate query triangles (a stem detected
// twice, a false stem beside a true one) then cannot pile up support for a wrong pose.
// Cells are accumulated as votes arrive (a flat hash table) and listed by their number of
// distinct voters, so asking for the best few cells after every few triangles is cheap.
class PoseVoter {
 public:
  PoseVoter(const MapIndexImpl& m, const std::vector<Eigen::Vector2d>& seed_xy,
            const std::optional<PriorPose>& prior, const Eigen::Vector2d& prior_xy,
            double tolerance, int min_votes);

  // Adds the votes of one query triangle (its vertices index seed_xy).
  void Add(const Triangle& qt);

  // The `max` cells with the most distinct voting seeds (at least `min_votes`), each as the
  // mean pose of its votes; ties in cell order.
  std::vector<Hypothesis> Best(size_t max) const;

 private:
  struct Cell {
    uint64_t key = 0;    // pose cell; kEmpty when the slot is free
    uint64_t seeds = 0;  // bit i = seed tree i voted here
    int voters = 0;      // distinct seeds: popcount(seeds)
    float cos = 0, sin = 0, x = 0, y = 0;  // sums over the votes
    int votes = 0;
  };
  void Vote(uint64_t seeds, const Rigid2& pose, double cos_yaw, double sin_yaw);
  size_t Probe(uint64_t key) const;  // the key's slot, or the free slot where it would go
  Cell& Slot(uint64_t key);           // inserts the key when missing

  const MapIndexImpl& m_;
  const std::vector<Eigen::Vector2d>& seed_xy_;
  const std::optional<PriorPose>& prior_;
  Eigen::Vector2d prior_xy_;
  double tol_;
  int min_votes_;
  std::vector<Cell> table_;     // open addressing, linear probing, size a power of two
  size_t used_ = 0;
  // by_voters_[v]: keys of the cells that reached v >= min_votes distinct voters (a cell that
  // gained more since also sits in a higher list: each list is checked against the cell).
  std::vector<std::vector<uint64_t>> by_voters_ = std::vector<std::vector<uint64_t>>(65);
  std::vector<std::pair<uint32_t, float>> found_;
};

}  // namespace forestmap::algorithms
