#pragma once
// Scoring relocalization answers against ground truth, with the definitions of the product's
// accuracy bar: a frame is ANSWERABLE when, under its true pose, at least 8 of its trees within
// 20 m lie within 0.5 m of a map tree (its MAPPED TREES IN SIGHT); CORRECT = localized within
// 0.5 m and 5 deg; STRICT = 0.2 m and 1 deg; WRONG = localized more than 1 m or 5 deg off. Recall
// is also reported over the RICH views, those with at least 12 mapped trees in sight.

#include <memory>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/core/kdtree.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

struct RelocCriteria {
  int answerable_min_trees = 8;
  double answerable_range = 20.0;    // m, horizontal, from the sensor
  double answerable_distance = 0.5;  // m, query tree to map tree
  double correct_xy = 0.5, correct_yaw_deg = 5.0;
  double strict_xy = 0.2, strict_yaw_deg = 1.0;
  double wrong_xy = 1.0, wrong_yaw_deg = 5.0;
  int rich_min_trees = 12;  // mapped trees in sight of a rich view
};

struct RelocSummary {
  int frames = 0, answerable = 0;
  int localized = 0, ambiguous = 0, not_found = 0;
  int correct = 0, strict = 0, wrong = 0;     // correct and strict count answerable frames only
  double recall = 0, strict_recall = 0;       // of answerable frames, in [0, 1]
  int rich = 0, rich_correct = 0;             // views with rich_min_trees mapped trees in sight
  double rich_recall = 0;                     // rich_correct / rich, in [0, 1]
  double wrong_rate = 0;                      // of all frames
  double error_xy_p50 = 0, error_xy_p95 = 0;  // m, of correct answers
  double error_yaw_p50 = 0;                   // deg, of correct answers
  double time_p50 = 0, time_p95 = 0, time_p99 = 0, time_max = 0;  // ms
};

struct PoseError {
  double xy = 0;   // m, horizontal distance between estimated and true sensor positions
  double yaw = 0;  // deg, heading difference
};

PoseError ComparePoses(const Pose3& estimate, const Pose3& truth);

// The p-quantile (p in [0, 1]) of `values` by the nearest-rank rule; 0 for no values.
double Percentile(std::vector<double> values, double p);

class RelocEvaluator {
 public:
  explicit RelocEvaluator(const std::vector<MapTree>& map, const RelocCriteria& criteria = {});

  // Scores the next answers against another map (a benchmark of many small maps); the answers
  // recorded so far stay.
  void UseMap(const std::vector<MapTree>& map);

  // Trees within answerable_range whose true position lies within answerable_distance of a map
  // tree.
  int MappedInSight(const std::vector<DetectedTree>& trees, const Pose3& map_from_sensor) const;
  bool Answerable(const std::vector<DetectedTree>& trees, const Pose3& map_from_sensor) const;

  // Records one answer; `truth` is map_from_sensor; `mapped_in_sight` (when known, >= 0) counts
  // the view among the rich ones. Returns whether it was wrong.
  bool Add(bool answerable, const Pose3& truth, const RelocalizeResult& result, double time_ms,
           int mapped_in_sight = -1);

  RelocSummary Summary() const;

 private:
  RelocCriteria criteria_;
  std::unique_ptr<KdTree<double, 2>> map_xy_;
  RelocSummary counts_;
  std::vector<double> error_xy_, error_yaw_, times_;
};

}  // namespace forestmap::algorithms
