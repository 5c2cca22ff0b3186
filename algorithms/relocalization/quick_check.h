#pragma once
// Internal to the pose search: the sequential test that rejects a wrong pose hypothesis after a
// few bitmap lookups, and the count of a pose's hits among the trees it is scored on.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "algorithms/relocalization/pose_search.h"

namespace forestmap::algorithms {

// Wald's sequential probability ratio test on query trees: does a pose put them on map trees
// at the rate of a true pose (quick_check_true_rate) or only as often as chance (the occupancy
// grid's occupied fraction)? Wrong poses are rejected after about four lookups.
class QuickCheck {
 public:
  QuickCheck(const MapIndexImpl& m, const LevelledQuery& q, const RelocalizerOptions& options)
      : m_(m), q_(q), quick_score_trees_(options.quick_score_trees) {
    // The chance rate p0 is the map's occupied share around the matched map triangle (a dense
    // stand beside a sparse one: each tested at its own density), in kLevels steps.
    const double p1 = options.quick_check_true_rate;
    max_p0_ = 0.5 * p1;
    for (int k = 0; k < kLevels; ++k) {
      const double p0 = kMinP0 + (max_p0_ - kMinP0) * k / (kLevels - 1);
      hit_[k] = std::log(p1 / p0);
      miss_[k] = std::log((1 - p1) / (1 - p0));
    }
    accept_ = std::log(1 / options.quick_check_false_accept);
    reject_ = std::log(options.quick_check_false_reject);
  }

  // The query trees (indices into the query) whose triangles are looked up next: the seeds.
  void SetPool(const std::vector<uint32_t>& pool) {
    pool_ = &pool;
    vertex_ = {UINT32_MAX, UINT32_MAX, UINT32_MAX};
  }

  // The query trees checked for poses from triangle `t` (vertices: indices into the pool): the
  // pool's trees, nearest to the triangle first (a triangle's pose is most accurate around it),
  // without its vertices.
  void SetTriangle(const Triangle& t) {
    if (t.vertex == vertex_) return;  // the same triangle at another level
    vertex_ = t.vertex;
    const std::vector<uint32_t>& pool = *pool_;
    const Eigen::Vector2d centroid =
        (q_.xy[pool[t.vertex[0]]] + q_.xy[pool[t.vertex[1]]] + q_.xy[pool[t.vertex[2]]]) / 3;
    by_distance_.clear();
    for (uint32_t k = 0; k < pool.size(); ++k) {
      if (k != t.vertex[0] && k != t.vertex[1] && k != t.vertex[2]) {
        const uint32_t i = pool[k];
        by_distance_.push_back({static_cast<float>((q_.xy[i] - centroid).squaredNorm()), i});
      }
    }
    std::sort(by_distance_.begin(), by_distance_.end());
  }

  // Under `pose`, the nearest query trees holding quick_score_trees inside the map's coverage
  // (ScoringPrefix): how many they are, how many lie inside, how many near a map tree.
  struct Scored {
    size_t prefix = 0;
    int inside = 0, hits = 0;
  };
  Scored Hits(const Rigid2& pose) const {
    const double c = std::cos(pose.yaw), s = std::sin(pose.yaw);
    const size_t n = std::min<size_t>(q_.xy.size(), quick_score_trees_);
    const bool deep = n > 0 && q_.xy[n - 1].norm() <= m_.coverage->deep_reach() &&
                      m_.coverage->Deep(pose.translation.x(), pose.translation.y());
    Scored scored;
    for (; scored.prefix < q_.xy.size() && scored.inside < static_cast<int>(quick_score_trees_);
         ++scored.prefix) {
      const Eigen::Vector2d& p = q_.xy[scored.prefix];
      const double x = c * p.x() - s * p.y() + pose.translation.x();
      const double y = s * p.x() + c * p.y() + pose.translation.y();
      const bool hit = m_.occupancy->Near(x, y);
      scored.hits += hit;
      scored.inside += hit || deep || m_.coverage->Covered(x, y);
    }
    return scored;
  }

  // The pose maps p to (c p.x - s p.y + tx, s p.x + c p.y + ty); (x, y): where its map
  // triangle lies.
  bool Passes(float c, float s, float tx, float ty, float x, float y) const {
    const double p0 = std::clamp(m_.occupancy->OccupiedFractionAt(x, y), kMinP0, max_p0_);
    const int level =
        static_cast<int>(std::lround((p0 - kMinP0) / (max_p0_ - kMinP0) * (kLevels - 1)));
    const double hit = hit_[level], miss = miss_[level];
    double llr = 0;
    for (const auto& [d2, i] : by_distance_) {
      const Eigen::Vector2d& p = q_.xy[i];
      const double px = c * p.x() - s * p.y() + tx, py = s * p.x() + c * p.y() + ty;
      if (m_.occupancy->Near(px, py)) {
        llr += hit;
      } else if (m_.coverage->Covered(px, py)) {  // beyond the coverage: no evidence either way
        llr += miss;
      }
      if (llr >= accept_) return true;
      if (llr <= reject_) return false;
    }
    return false;
  }

 private:
  const MapIndexImpl& m_;
  const LevelledQuery& q_;
  const size_t quick_score_trees_;
  const std::vector<uint32_t>* pool_ = nullptr;                            // SetPool's
  std::vector<std::pair<float, uint32_t>> by_distance_;                    // the check order
  std::array<uint32_t, 3> vertex_ = {UINT32_MAX, UINT32_MAX, UINT32_MAX};  // ... for this triangle
  static constexpr int kLevels = 64;
  static constexpr double kMinP0 = 0.005;
  double max_p0_ = 0.375;
  double hit_[kLevels] = {}, miss_[kLevels] = {};
  double accept_ = 0, reject_ = 0;
};

}  // namespace forestmap::algorithms
