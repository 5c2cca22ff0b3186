#pragma once
// Relocalization cases where a view sees more forest than its map covers, built from one stem
// map: the map cut by a straight line (the edge of a survey), and neighbouring circular survey
// plots, each its own map. Geometry only: the views come from the view simulator, drawn in the
// whole stem map. Frames: the stem map's (m). Randomness from the caller's generator.

#include <optional>
#include <random>
#include <utility>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

// A straight line: the points p with normal . (p - point) = 0 (normal of unit length).
struct Line2 {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();
  double SignedDistance(const Eigen::Vector2d& p) const { return normal.dot(p - point); }
};

// A line of uniform random direction through a point drawn uniformly in the middle half (along
// each axis) of the box [lo, hi]: it cuts a map roughly in two.
Line2 RandomCut(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, std::mt19937& rng);

// The trees on the line's negative side (signed distance <= 0): the surveyed half.
std::vector<MapTree> KeepBehind(const std::vector<MapTree>& trees, const Line2& cut);

// The trees within `radius` (m) of `centre`: a circular survey plot.
std::vector<MapTree> CircularPlot(const std::vector<MapTree>& trees, const Eigen::Vector2d& centre,
                                  double radius);

// Centres of two neighbouring circular plots of `radius` (m), both inside the box [lo, hi] by
// at least the radius, `min_apart` to `max_apart` (m) apart in a uniform direction; nullopt
// when 1,000 draws find no such pair (the box is too small).
std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> NeighbourPlots(
    const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double radius, double min_apart,
    double max_apart, std::mt19937& rng);

}  // namespace forestmap::algorithms
