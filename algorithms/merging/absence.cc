#include "algorithms/merging/absence.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "algorithms/core/check.h"

namespace forestmap::algorithms {
namespace {

// A trunk seen from the sensor: horizontal range, bearing and the half-angle it covers.
struct Silhouette {
  double range = 0;       // m
  double bearing = 0;     // rad, map frame
  double half_angle = 0;  // rad, trunk + margin + pose uncertainty
  int map_index = -1;     // the map tree it is, or -1 for a detection
  int seen_index = -1;    // for a detection: the map tree in whose gate it lies, else -1
};

// Between two bearings in [-pi, pi] (std::atan2's).
double AngleBetween(double a, double b) {
  const double d = std::abs(a - b);
  return d > M_PI ? 2 * M_PI - d : d;
}

// The occluders (trunks and detections that can hide a tree) by bearing: each listed in every bin
// of kBins around the sensor that its angular extent [bearing - half_angle, bearing + half_angle]
// touches, so that those that may overlap a target's extent are found in the bins of the target's.
class BearingBins {
 public:
  static constexpr int kBins = 256;
  void Add(const Silhouette& s, int index) {
    ForBins(s, [&](int bin) { bins_[bin].push_back(index); });
  }
  // Calls visit(index) for each occluder in the bins of `target` (an index may come again) until
  // it returns true; returns whether it did.
  template <typename Visit>
  bool Any(const Silhouette& target, const Visit& visit) const {
    bool found = false;
    ForBins(target, [&](int bin) {
      for (const int index : bins_[bin]) {
        if (!found && visit(index)) found = true;
      }
    });
    return found;
  }

 private:
  template <typename Each>
  static void ForBins(const Silhouette& s, const Each& each) {
    constexpr double kWidth = 2 * M_PI / kBins;
    const double from = s.bearing - s.half_angle, to = s.bearing + s.half_angle;
    if (to - from >= 2 * M_PI - kWidth) {
      for (int bin = 0; bin < kBins; ++bin) each(bin);
      return;
    }
    const long first = std::lround(std::floor(from / kWidth)),
               last = std::lround(std::floor(to / kWidth));
    for (long k = first; k <= last; ++k) each(static_cast<int>(((k % kBins) + kBins) % kBins));
  }
  std::array<std::vector<int>, kBins> bins_;
};

Silhouette SilhouetteOf(const Eigen::Vector2d& sensor_xy, const Eigen::Vector2d& xy, double dbh,
                        const AbsenceObservation& observation, const AbsenceOptions& options) {
  Silhouette s;
  const Eigen::Vector2d d = xy - sensor_xy;
  s.range = d.norm();
  s.bearing = std::atan2(d.y(), d.x());
  const double diameter = IsKnown(dbh) && dbh > 0 ? dbh : options.unknown_dbh;
  const double radius = diameter / 2 + options.occlusion_margin;
  const double trunk = s.range > radius ? std::asin(radius / s.range) : M_PI / 2;
  // A wrong sensor position turns the line of sight to a trunk at range r by about sigma / r;
  // a wrong heading turns the detections (placed in the map with it) by sigma_yaw.
  const double pose =
      observation.pose_sigma_xy / std::max(s.range, radius) + observation.pose_sigma_yaw;
  s.half_angle = trunk + pose;
  return s;
}

double Quantile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  const size_t k =
      std::min(values.size() - 1,
               static_cast<size_t>(std::ceil(q * static_cast<double>(values.size())) - 1));
  return values[k];
}

}  // namespace

void AbsenceOptions::Check() const {
  Require(range >= 0, "AbsenceOptions.range must be >= 0 m", range);
  Require(range_quantile > 0 && range_quantile <= 1,
          "AbsenceOptions.range_quantile must be in (0, 1]", range_quantile);
  Require(min_learn_trees >= 1, "AbsenceOptions.min_learn_trees must be >= 1", min_learn_trees);
  Require(detection_probability >= 0 && detection_probability < 1,
          "AbsenceOptions.detection_probability must be in [0, 1)", detection_probability);
  Require(max_detection_probability > 0 && max_detection_probability < 1,
          "AbsenceOptions.max_detection_probability must be in (0, 1)", max_detection_probability);
  Require(far_ratio >= 0 && far_ratio <= 1, "AbsenceOptions.far_ratio must be in [0, 1]",
          far_ratio);
  Require(edge_margin >= 0, "AbsenceOptions.edge_margin must be >= 0 m", edge_margin);
  Require(min_range >= 0, "AbsenceOptions.min_range must be >= 0 m", min_range);
  Require(gate_distance > 0, "AbsenceOptions.gate_distance must be > 0 m", gate_distance);
  Require(gate_sigmas > 0, "AbsenceOptions.gate_sigmas must be > 0", gate_sigmas);
  Require(unknown_dbh > 0, "AbsenceOptions.unknown_dbh must be > 0 m", unknown_dbh);
  Require(occlusion_margin >= 0, "AbsenceOptions.occlusion_margin must be >= 0 m",
          occlusion_margin);
}

const char* ToString(Visibility visibility) {
  switch (visibility) {
    case Visibility::kNotExpected:
      return "not_expected";
    case Visibility::kSeen:
      return "seen";
    case Visibility::kMissed:
      return "missed";
  }
  return "unknown";
}

AbsenceResult ExpectTrees(std::span<const MapTree> map_trees, const AbsenceObservation& observation,
                          const AbsenceOptions& options) {
  return ExpectTrees(map_trees, {}, {}, observation, options);
}

AbsenceResult ExpectTrees(std::span<const MapTree> established, std::span<const char> standing,
                          std::span<const MapTree> candidates,
                          const AbsenceObservation& observation, const AbsenceOptions& options) {
  options.Check();
  Require(observation.map_from_sensor.matrix().allFinite(), "the pose must be finite");
  Require(observation.pose_sigma_xy >= 0 && observation.pose_sigma_yaw >= 0,
          "pose sigmas must be >= 0");
  const Eigen::Vector2d sensor_xy = observation.map_from_sensor.translation().head<2>();
  std::vector<MapTree> map_trees(established.begin(), established.end());
  map_trees.insert(map_trees.end(), candidates.begin(), candidates.end());
  const size_t n = map_trees.size(), n_established = established.size();
  std::vector<Silhouette> silhouettes;
  silhouettes.reserve(n + observation.trees.size());
  for (size_t i = 0; i < n; ++i) {
    silhouettes.push_back(SilhouetteOf(sensor_xy, map_trees[i].position.head<2>(), map_trees[i].dbh,
                                       observation, options));
    silhouettes.back().map_index = static_cast<int>(i);
  }
  // Sightings: a detection sees the nearest tree within its gate (the gate grows with the position
  // error the pose uncertainty causes at the tree's range); one stem, one tree, as the merge
  // associates. A neighbour in the same gate is not seen by it (a felled tree beside a standing
  // one), and is hidden by it when the detection is nearer the sensor.
  std::vector<char> seen(n, 0);
  std::vector<double> detected_ranges;
  for (const DetectedTree& detection : observation.trees) {
    const Eigen::Vector3d map_xyz = observation.map_from_sensor * detection.position;
    if (!map_xyz.allFinite()) continue;
    Silhouette s = SilhouetteOf(sensor_xy, map_xyz.head<2>(), detection.dbh, observation, options);
    const double gate =
        std::max(options.gate_distance,
                 options.gate_sigmas *
                     std::hypot(observation.pose_sigma_xy, s.range * observation.pose_sigma_yaw));
    double best = gate;
    for (size_t i = 0; i < n; ++i) {
      const double d = (map_trees[i].position.head<2>() - map_xyz.head<2>()).norm();
      if (d <= best) {
        best = d;
        s.seen_index = static_cast<int>(i);
      }
    }
    if (s.seen_index >= 0) {
      const size_t i = static_cast<size_t>(s.seen_index);
      if (!seen[i] && i < n_established) detected_ranges.push_back(silhouettes[i].range);
      seen[i] = 1;
    }
    silhouettes.push_back(s);
  }
  AbsenceResult result;
  result.trees.resize(n);
  for (size_t i = 0; i < n; ++i) {
    result.trees[i].id = map_trees[i].id;
    result.trees[i].range = silhouettes[i].range;
    if (seen[i]) result.trees[i].visibility = Visibility::kSeen;
  }
  result.detected_map_trees = static_cast<int>(detected_ranges.size());
  const bool can_learn = result.detected_map_trees >= options.min_learn_trees;
  if (options.range > 0) {
    result.range = options.range;
    result.range_source = SensorModelSource::kStated;
  } else if (can_learn) {
    result.range = Quantile(detected_ranges, options.range_quantile);
    result.range_source = SensorModelSource::kLearned;
  } else {
    return result;  // the range is unknown: no evidence either way
  }
  // Expected: in range (not at its edge) and not in the shadow of a nearer trunk. A detection
  // in the tree's own gate is the tree, not an occluder.
  std::vector<char> expected(n, 0);
  const double far = result.range - options.edge_margin;
  BearingBins occluders;
  for (size_t k = 0; k < silhouettes.size(); ++k) {
    // A candidate may be a false stem: it hides nothing.
    if (silhouettes[k].map_index < static_cast<int>(n_established)) {
      occluders.Add(silhouettes[k], static_cast<int>(k));
    }
  }
  for (size_t i = 0; i < n; ++i) {
    const Silhouette& target = silhouettes[i];
    if (target.range < options.min_range || target.range > far) continue;
    const bool hidden = occluders.Any(target, [&](int k) {
      const Silhouette& other = silhouettes[static_cast<size_t>(k)];
      if (other.map_index == static_cast<int>(i) || other.seen_index == static_cast<int>(i) ||
          other.range >= target.range) {
        return false;
      }
      return AngleBetween(other.bearing, target.bearing) < other.half_angle + target.half_angle;
    });
    expected[i] = !hidden;
  }
  const auto shape = [&](double r) {
    return 1.0 - (1.0 - options.far_ratio) * std::min(r / result.range, 1.0);
  };
  // The detection rate is learned from the trees known to stand (seen since the survey) when
  // enough of them are expected: an established tree may be gone, which would make the detector
  // look worse than it is; else from every established tree (a lower bound: conservative).
  for (const bool only_standing : {true, false}) {
    result.learn_seen = 0;
    result.learn_weight = 0;
    for (size_t i = 0; i < n_established; ++i) {
      if (!expected[i] || (only_standing && !(i < standing.size() && standing[i]))) continue;
      result.learn_weight += shape(silhouettes[i].range);
      result.learn_seen += seen[i];
    }
    result.learned_from_standing = only_standing;
    if (result.learn_weight >= options.min_learn_trees) break;
  }
  const double seen_expected = result.learn_seen, expected_detections = result.learn_weight;
  if (options.detection_probability > 0) {
    result.detection_probability = options.detection_probability;
    result.probability_source = SensorModelSource::kStated;
  } else if (seen_expected >= options.min_learn_trees && expected_detections > 0) {
    result.detection_probability =
        std::min(options.max_detection_probability, seen_expected / expected_detections);
    result.probability_source = SensorModelSource::kLearned;
  } else {
    return result;  // the detection rate is unknown: no evidence either way
  }
  for (size_t i = 0; i < n; ++i) {
    TreeVisibility& tree = result.trees[i];
    if (!expected[i]) continue;
    tree.detection_probability = result.detection_probability * shape(tree.range);
    ++result.expected;
    if (seen[i]) {
      ++result.seen;
    } else {
      tree.visibility = Visibility::kMissed;
      ++result.missed;
    }
  }
  return result;
}

void SensorPool::Add(const AbsenceResult& frame) {
  if (frame.range_source == SensorModelSource::kLearned) range = frame.range;
  (frame.learned_from_standing ? standing_seen : all_seen) += frame.learn_seen;
  (frame.learned_from_standing ? standing_weight : all_weight) += frame.learn_weight;
}

AbsenceOptions SensorPool::Apply(const AbsenceOptions& base) const {
  AbsenceOptions options = base;
  if (options.range == 0) options.range = range;
  if (options.detection_probability == 0) {
    const double min_weight = options.min_learn_trees;
    const bool standing = standing_weight >= min_weight;
    const double seen = standing ? standing_seen : all_seen;
    const double weight = standing ? standing_weight : all_weight;
    if (weight >= min_weight) {
      options.detection_probability = std::min(options.max_detection_probability, seen / weight);
    }
  }
  return options;
}

}  // namespace forestmap::algorithms
