#include "algorithms/evaluation/reloc_evaluation.h"

#include <algorithm>

namespace forestmap::algorithms {
double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const size_t i = std::min(values.size() - 1, static_cast<size_t>(p * values.size()));
  return values[i];
}

PoseError ComparePoses(const Pose3& estimate, const Pose3& truth) {
  PoseError e;
  e.xy = (estimate.translation() - truth.translation()).head<2>().norm();
  e.yaw = std::abs(YawOf(estimate.linear() * truth.linear().transpose())) * 180.0 / M_PI;
  return e;
}

RelocEvaluator::RelocEvaluator(const std::vector<MapTree>& map, const RelocCriteria& criteria)
    : criteria_(criteria) {
  UseMap(map);
}

void RelocEvaluator::UseMap(const std::vector<MapTree>& map) {
  std::vector<KdTree<double, 2>::Point> xy;
  xy.reserve(map.size());
  for (const MapTree& t : map) xy.push_back({t.position.x(), t.position.y()});
  map_xy_ = std::make_unique<KdTree<double, 2>>(std::move(xy));
}

bool RelocEvaluator::Answerable(const std::vector<DetectedTree>& trees,
                                const Pose3& map_from_sensor) const {
  return MappedInSight(trees, map_from_sensor) >= criteria_.answerable_min_trees;
}

int RelocEvaluator::MappedInSight(const std::vector<DetectedTree>& trees,
                                  const Pose3& map_from_sensor) const {
  int matched = 0;
  const double max_d2 = criteria_.answerable_distance * criteria_.answerable_distance;
  for (const DetectedTree& tree : trees) {
    const Eigen::Vector3d p = map_from_sensor * tree.position;
    if ((p - map_from_sensor.translation()).head<2>().norm() > criteria_.answerable_range) {
      continue;
    }
    const auto [index, d2] = map_xy_->Nearest({p.x(), p.y()});
    matched += index >= 0 && d2 <= max_d2;
  }
  return matched;
}

bool RelocEvaluator::Add(bool answerable, const Pose3& truth, const RelocalizeResult& result,
                         double time_ms, int mapped_in_sight) {
  RelocSummary& c = counts_;
  const bool rich = mapped_in_sight >= criteria_.rich_min_trees;
  c.rich += rich;
  ++c.frames;
  c.answerable += answerable;
  times_.push_back(time_ms);
  bool wrong = false;
  switch (result.status) {
    case RelocalizeStatus::kAmbiguous:
      ++c.ambiguous;
      break;
    case RelocalizeStatus::kNotFound:
      ++c.not_found;
      break;
    case RelocalizeStatus::kLocalized: {
      ++c.localized;
      const PoseError e = ComparePoses(result.map_from_sensor, truth);
      wrong = e.xy > criteria_.wrong_xy || e.yaw > criteria_.wrong_yaw_deg;
      c.wrong += wrong;
      if (answerable && e.xy <= criteria_.correct_xy && e.yaw <= criteria_.correct_yaw_deg) {
        ++c.correct;
        c.rich_correct += rich;
        error_xy_.push_back(e.xy);
        error_yaw_.push_back(e.yaw);
      }
      c.strict += answerable && e.xy <= criteria_.strict_xy && e.yaw <= criteria_.strict_yaw_deg;
      break;
    }
  }
  return wrong;
}

RelocSummary RelocEvaluator::Summary() const {
  RelocSummary s = counts_;
  if (s.answerable > 0) {
    s.recall = static_cast<double>(s.correct) / s.answerable;
    s.strict_recall = static_cast<double>(s.strict) / s.answerable;
  }
  if (s.rich > 0) s.rich_recall = static_cast<double>(s.rich_correct) / s.rich;
  if (s.frames > 0) s.wrong_rate = static_cast<double>(s.wrong) / s.frames;
  s.error_xy_p50 = Percentile(error_xy_, 0.5);
  s.error_xy_p95 = Percentile(error_xy_, 0.95);
  s.error_yaw_p50 = Percentile(error_yaw_, 0.5);
  s.time_p50 = Percentile(times_, 0.5);
  s.time_p95 = Percentile(times_, 0.95);
  s.time_p99 = Percentile(times_, 0.99);
  s.time_max = Percentile(times_, 1.0);
  return s;
}

}  // namespace forestmap::algorithms
