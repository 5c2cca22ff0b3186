#include "algorithms/simulation/view_simulator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "algorithms/core/check.h"
#include "algorithms/core/random.h"

namespace forestmap::algorithms {

namespace {

constexpr double kUnknownDbhRadius = 0.15;   // m, trunk radius assumed for occlusion
constexpr double kFalseStemClearance = 1.0;  // m, false stems keep this far from map trees
constexpr double kMaxTilt = 1.5;             // rad
constexpr double kMinDetectedDbh = 0.01;     // m

// Sorted disjoint angular intervals within [-pi, pi]: the shadows cast by trunks.
class ShadowSet {
 public:
  void Add(double lo, double hi) {
    if (hi - lo >= 2 * M_PI) return AddRaw(-M_PI, M_PI);
    if (lo < -M_PI) {
      AddRaw(lo + 2 * M_PI, M_PI);
      lo = -M_PI;
    }
    if (hi > M_PI) {
      AddRaw(-M_PI, hi - 2 * M_PI);
      hi = M_PI;
    }
    AddRaw(lo, hi);
  }
  bool Covers(double angle) const {
    auto it = intervals_.upper_bound(angle);
    if (it == intervals_.begin()) return false;
    return angle <= std::prev(it)->second;
  }

 private:
  void AddRaw(double lo, double hi) {
    auto it = intervals_.upper_bound(lo);
    if (it != intervals_.begin() && std::prev(it)->second >= lo) {
      lo = std::prev(it)->first;
      hi = std::max(hi, std::prev(it)->second);
      it = intervals_.erase(std::prev(it));
    }
    while (it != intervals_.end() && it->first <= hi) {
      hi = std::max(hi, it->second);
      it = intervals_.erase(it);
    }
    intervals_[lo] = hi;
  }
  std::map<double, double> intervals_;  // rad, start -> end
};

// Roll and pitch uniform in [-max_tilt, max_tilt], kept when the z axis tilts <= max_tilt.
std::pair<double, double> DrawTilt(double max_tilt, Rng& rng) {
  if (max_tilt <= 0) return {0.0, 0.0};
  while (true) {
    const double roll = Uniform(rng, -max_tilt, max_tilt);
    const double pitch = Uniform(rng, -max_tilt, max_tilt);
    if (std::cos(roll) * std::cos(pitch) >= std::cos(max_tilt)) return {roll, pitch};
  }
}

// A unit vector within ~sd rad (per axis) of `direction`.
Eigen::Vector3d PerturbDirection(const Eigen::Vector3d& direction, double sd, Rng& rng) {
  const Eigen::Vector3d u = direction.unitOrthogonal();
  const Eigen::Vector3d v = direction.cross(u);
  return (direction + Gaussian(rng, sd) * u + Gaussian(rng, sd) * v).normalized();
}

// The view with its detections (and their truth ids) in random order: a detector's output order
// must not reveal which detections are true or near.
SimulatedView Shuffled(const SimulatedView& view, Rng& rng) {
  std::vector<size_t> order(view.trees.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  SimulatedView shuffled{view.map_from_sensor, {}, {}, view.visible_trees};
  for (size_t i : order) {
    shuffled.trees.push_back(view.trees[i]);
    shuffled.truth_ids.push_back(view.truth_ids[i]);
  }
  return shuffled;
}

}  // namespace

void ViewOptions::Check() const {
  Require(std::isfinite(range) && range > 0, "ViewOptions.range must be > 0 m", range);
  Require(miss_rate >= 0 && miss_rate <= 1, "ViewOptions.miss_rate must be in [0, 1]", miss_rate);
  Require(far_miss_rate <= 1, "ViewOptions.far_miss_rate must be <= 1 (< 0: none)", far_miss_rate);
  Require(std::isfinite(noise_per_metre) && noise_per_metre >= 0,
          "ViewOptions.noise_per_metre must be >= 0 m/m", noise_per_metre);
  Require(std::isfinite(false_rate) && false_rate >= 0, "ViewOptions.false_rate must be >= 0",
          false_rate);
  Require(std::isfinite(position_noise) && position_noise >= 0,
          "ViewOptions.position_noise must be >= 0 m", position_noise);
  Require(std::isfinite(dbh_noise) && dbh_noise >= 0, "ViewOptions.dbh_noise must be >= 0 m",
          dbh_noise);
  Require(std::isfinite(axis_noise) && axis_noise >= 0, "ViewOptions.axis_noise must be >= 0 rad",
          axis_noise);
  Require(max_tilt >= 0 && max_tilt <= kMaxTilt, "ViewOptions.max_tilt must be in [0, 1.5] rad",
          max_tilt);
  Require(std::isfinite(sensor_height), "ViewOptions.sensor_height must be finite m",
          sensor_height);
}

ViewSimulator::ViewSimulator(std::vector<MapTree> map) : map_(std::move(map)), grid_(map_) {}

std::vector<int> ViewSimulator::VisibleTrees(const Eigen::Vector2d& position_xy, double range,
                                             bool occlusion) const {
  struct Candidate {
    int index;
    double distance, bearing, half_angle;  // m, rad, rad
  };
  std::vector<Candidate> candidates;
  for (int i : grid_.InRadius(position_xy, range)) {
    const Eigen::Vector2d offset = map_[i].position.head<2>() - position_xy;
    const double distance = offset.norm();
    const double dbh = map_[i].dbh;
    const double radius = IsKnown(dbh) && dbh > 0 ? dbh / 2 : kUnknownDbhRadius;
    if (distance <= radius) continue;  // the sensor cannot be inside a trunk: skip that tree
    candidates.push_back(
        {i, distance, std::atan2(offset.y(), offset.x()), std::asin(radius / distance)});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.distance != b.distance ? a.distance < b.distance : a.index < b.index;
  });
  std::vector<int> visible;
  ShadowSet shadows;
  for (const Candidate& c : candidates) {
    if (!occlusion) {
      visible.push_back(c.index);
      continue;
    }
    if (!shadows.Covers(c.bearing)) visible.push_back(c.index);
    shadows.Add(c.bearing - c.half_angle, c.bearing + c.half_angle);  // hidden trunks cast too
  }
  return visible;
}

SimulatedView ViewSimulator::Simulate(const Eigen::Vector2d& position_xy, double yaw,
                                      const ViewOptions& options) const {
  options.Check();
  Require(position_xy.allFinite(), "ViewSimulator::Simulate: position must be finite, x",
          position_xy.x());
  Require(std::isfinite(yaw), "ViewSimulator::Simulate: yaw must be finite rad", yaw);
  Rng rng(options.seed);
  auto ground_z = [&](const Eigen::Vector2d& p) {
    const int nearest = grid_.Nearest(p);
    return nearest >= 0 && IsKnown(map_[nearest].position.z()) ? map_[nearest].position.z() : 0.0;
  };
  SimulatedView view;
  const auto [roll, pitch] = DrawTilt(options.max_tilt, rng);
  view.map_from_sensor.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                      .toRotationMatrix();
  view.map_from_sensor.translation() = Eigen::Vector3d(
      position_xy.x(), position_xy.y(), ground_z(position_xy) + options.sensor_height);
  const Pose3 sensor_from_map = view.map_from_sensor.inverse();
  const Eigen::Vector3d up_in_sensor = sensor_from_map.linear() * Eigen::Vector3d::UnitZ();

  // The chance of missing a tree and the noise of its position, at its horizontal range.
  auto miss_rate = [&](const Eigen::Vector3d& map_point) {
    if (options.far_miss_rate < 0) return options.miss_rate;
    const double share = std::min(1.0, (map_point.head<2>() - position_xy).norm() / options.range);
    return options.miss_rate + share * (options.far_miss_rate - options.miss_rate);
  };
  auto detect = [&](Eigen::Vector3d map_point, double dbh, int64_t truth_id) {
    const double noise = options.position_noise +
                         options.noise_per_metre * (map_point.head<2>() - position_xy).norm();
    for (int a = 0; a < 3; ++a) map_point[a] += Gaussian(rng, noise);
    DetectedTree tree;
    tree.position = sensor_from_map * map_point;
    if (IsKnown(dbh)) tree.dbh = std::max(kMinDetectedDbh, dbh + Gaussian(rng, options.dbh_noise));
    tree.axis = PerturbDirection(up_in_sensor, options.axis_noise, rng);
    tree.score = Uniform(rng, 0.5, 1.0);  // uninformative: false stems score alike
    view.trees.push_back(tree);
    view.truth_ids.push_back(truth_id);
  };

  const std::vector<int> visible = VisibleTrees(position_xy, options.range, options.occlusion);
  view.visible_trees = static_cast<int>(visible.size());
  for (int i : visible) {
    const MapTree& tree = map_[i];
    if (std::bernoulli_distribution(miss_rate(tree.position))(rng)) continue;
    const double z = IsKnown(tree.position.z()) ? tree.position.z() : 0.0;
    detect({tree.position.x(), tree.position.y(), z}, tree.dbh, tree.id);
  }

  const double expected_false = options.false_rate * static_cast<double>(view.trees.size());
  const int n_false = expected_false > 0 ? std::poisson_distribution<int>(expected_false)(rng) : 0;
  std::uniform_int_distribution<size_t> any_tree(0, map_.empty() ? 0 : map_.size() - 1);
  for (int f = 0; f < n_false; ++f) {
    for (int t = 0; t < kMaxPlacementTries; ++t) {
      const double r = options.range * std::sqrt(Uniform(rng, 0.0, 1.0));
      const double bearing = Uniform(rng, -M_PI, M_PI);
      const Eigen::Vector2d p =
          position_xy + r * Eigen::Vector2d(std::cos(bearing), std::sin(bearing));
      if (!grid_.InRadius(p, kFalseStemClearance).empty()) continue;
      detect({p.x(), p.y(), ground_z(p)}, map_.empty() ? kUnknown : map_[any_tree(rng)].dbh, -1);
      break;
    }
  }

  return Shuffled(view, rng);
}

std::vector<Eigen::Vector3d> ViewSimulator::SamplePoses(int count, double margin, unsigned seed,
                                                        int min_trees, double range) const {
  Require(count >= 0, "SamplePoses: count must be >= 0", count);
  Require(std::isfinite(margin) && margin >= 0, "SamplePoses: margin must be >= 0 m", margin);
  Require(std::isfinite(range) && range > 0, "SamplePoses: range must be > 0 m", range);
  Require(min_trees >= 0, "SamplePoses: min_trees must be >= 0", min_trees);
  Require(!map_.empty(), "SamplePoses: the map is empty, trees", 0);
  const Eigen::Vector2d lo = grid_.min_corner().array() + margin;
  const Eigen::Vector2d hi = grid_.max_corner().array() - margin;
  Require(lo.x() <= hi.x() && lo.y() <= hi.y(),
          "SamplePoses: margin leaves no room inside the map's extent, margin", margin);
  Rng rng(seed);
  std::vector<Eigen::Vector3d> poses;
  const int64_t max_draws = 1000 * static_cast<int64_t>(count);
  for (int64_t draw = 0; draw < max_draws && static_cast<int>(poses.size()) < count; ++draw) {
    const Eigen::Vector2d p(Uniform(rng, lo.x(), std::nextafter(hi.x(), INFINITY)),
                            Uniform(rng, lo.y(), std::nextafter(hi.y(), INFINITY)));
    const double yaw = Uniform(rng, -M_PI, M_PI);
    if (min_trees > 0 && static_cast<int>(grid_.InRadius(p, range).size()) < min_trees) continue;
    poses.emplace_back(p.x(), p.y(), yaw);
  }
  return poses;
}

std::vector<Eigen::Vector3d> SamplePoses(const std::vector<MapTree>& map, int count, double margin,
                                         unsigned seed, int min_trees, double range) {
  return ViewSimulator(map).SamplePoses(count, margin, seed, min_trees, range);
}

}  // namespace forestmap::algorithms
