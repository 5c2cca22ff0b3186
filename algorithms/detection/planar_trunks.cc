#include "algorithms/detection/planar_trunks.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {
namespace {

struct Return {
  int beam = 0;
  double range = 0;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
};

// Median point by coordinate-wise medians (robust to a stray return at the group's ends).
Eigen::Vector2d MedianPoint(const std::vector<Return>& group) {
  std::vector<double> xs, ys;
  for (const Return& r : group) {
    xs.push_back(r.p.x());
    ys.push_back(r.p.y());
  }
  std::nth_element(xs.begin(), xs.begin() + xs.size() / 2, xs.end());
  std::nth_element(ys.begin(), ys.begin() + ys.size() / 2, ys.end());
  return {xs[xs.size() / 2], ys[ys.size() / 2]};
}

void FitGroup(const std::vector<Return>& group, const PlanarTrunkOptions& options,
              PlanarTrunkResult& result) {
  ++result.groups;
  if ((group.front().p - group.back().p).norm() > options.max_width) {
    ++result.rejected_width;
    return;
  }
  const Eigen::Vector2d median = MedianPoint(group);
  std::vector<Eigen::Vector2d> points;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Return& r : group) {
    if ((r.p - median).norm() <= options.median_radius) {
      points.push_back(r.p);
      mean += r.p;
    }
  }
  if (static_cast<int>(points.size()) < options.min_points) {
    ++result.rejected_points;
    return;
  }
  mean /= static_cast<double>(points.size());
  const KasaResult kasa = FitCircleKasa(points);
  if (!kasa.ok) {
    ++result.rejected_fit;
    return;
  }
  Circle circle = kasa.circle;
  double rms = RefineCircleGeometric(points, circle, 0).rms;
  if (options.geometric_refinement) {
    const GeometricFitResult refined = RefineCircleGeometric(points, circle);
    circle = refined.circle;
    rms = refined.rms;
  }
  // The scanner sees the near side of a trunk: the centre lies beyond the points.
  const bool facing = circle.center.norm() > mean.norm();
  if (!facing || circle.radius < options.min_radius || circle.radius > options.max_radius ||
      rms > options.max_rms) {
    ++result.rejected_fit;
    return;
  }
  PlanarTrunk trunk;
  trunk.circle = circle;
  trunk.points = static_cast<int>(points.size());
  trunk.rms = rms;
  trunk.first_beam = group.front().beam;
  trunk.last_beam = group.back().beam;
  trunk.tree.position = Eigen::Vector3d(circle.center.x(), circle.center.y(), 0.0);
  trunk.tree.dbh = 2.0 * circle.radius;
  trunk.tree.axis = Eigen::Vector3d::UnitZ();
  trunk.tree.score = 1.0 / (1.0 + (rms / 0.01) * (rms / 0.01));
  result.trunks.push_back(trunk);
}

}  // namespace

void PlanarTrunkOptions::Check() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("PlanarTrunkOptions: ") + what);
  };
  require(min_range >= 0 && max_range > min_range, "need 0 <= min_range < max_range");
  require(fov_width > 0 && fov_width <= 2 * M_PI, "fov_width must be in (0, 2 pi]");
  require(range_jump > 0 && range_jump_ratio >= 0, "range_jump must be > 0, ratio >= 0");
  require(max_gap_beams >= 0, "max_gap_beams must be >= 0");
  require(max_width > 0 && median_radius > 0, "max_width and median_radius must be > 0");
  require(min_points >= 3, "min_points must be >= 3");
  require(min_radius > 0 && max_radius > min_radius, "need 0 < min_radius < max_radius");
  require(max_rms > 0, "max_rms must be > 0");
}

PlanarTrunkResult DetectPlanarTrunks(const PlanarScan& scan, const PlanarTrunkOptions& options) {
  options.Check();
  if (scan.angles.size() != scan.ranges.size()) {
    throw std::invalid_argument("PlanarScan: " + std::to_string(scan.angles.size()) +
                                " angles but " + std::to_string(scan.ranges.size()) + " ranges");
  }
  PlanarTrunkResult result;
  std::vector<Return> group;
  int last_beam = -1;
  for (int i = 0; i < static_cast<int>(scan.size()); ++i) {
    const double range = scan.ranges[i], angle = scan.angles[i];
    const bool in_fov = std::abs(WrapAngle(angle - options.fov_center)) <= 0.5 * options.fov_width;
    if (!std::isfinite(range) || !std::isfinite(angle) || range < options.min_range ||
        range > options.max_range || !in_fov) {
      continue;
    }
    ++result.returns_kept;
    const Return r{i, range, Eigen::Vector2d(range * std::cos(angle), range * std::sin(angle))};
    if (!group.empty()) {
      const double jump = std::max(options.range_jump, options.range_jump_ratio * range);
      if (i - last_beam - 1 > options.max_gap_beams ||
          std::abs(range - group.back().range) > jump) {
        FitGroup(group, options, result);
        group.clear();
      }
    }
    group.push_back(r);
    last_beam = i;
  }
  if (!group.empty()) FitGroup(group, options, result);
  return result;
}

}  // namespace forestmap::algorithms
