#include "algorithms/evaluation/coverage_cases.h"

#include <cmath>

namespace forestmap::algorithms {
namespace {

double Draw(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

}  // namespace

Line2 RandomCut(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, std::mt19937& rng) {
  const Eigen::Vector2d quarter = 0.25 * (hi - lo);
  Line2 line;
  line.point = {Draw(rng, lo.x() + quarter.x(), hi.x() - quarter.x()),
                Draw(rng, lo.y() + quarter.y(), hi.y() - quarter.y())};
  const double angle = Draw(rng, -M_PI, M_PI);
  line.normal = {std::cos(angle), std::sin(angle)};
  return line;
}

std::vector<MapTree> KeepBehind(const std::vector<MapTree>& trees, const Line2& cut) {
  std::vector<MapTree> kept;
  for (const MapTree& t : trees) {
    if (cut.SignedDistance(t.position.head<2>()) <= 0) kept.push_back(t);
  }
  return kept;
}

std::vector<MapTree> CircularPlot(const std::vector<MapTree>& trees, const Eigen::Vector2d& centre,
                                  double radius) {
  std::vector<MapTree> plot;
  for (const MapTree& t : trees) {
    if ((t.position.head<2>() - centre).norm() <= radius) plot.push_back(t);
  }
  return plot;
}

std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> NeighbourPlots(
    const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, double radius, double min_apart,
    double max_apart, std::mt19937& rng) {
  const Eigen::Vector2d inner_lo = lo.array() + radius, inner_hi = hi.array() - radius;
  if ((inner_hi - inner_lo).minCoeff() <= 0) return std::nullopt;
  auto inside = [&](const Eigen::Vector2d& p) {
    return (p.array() >= inner_lo.array()).all() && (p.array() <= inner_hi.array()).all();
  };
  constexpr int kDraws = 1000;
  for (int i = 0; i < kDraws; ++i) {
    const Eigen::Vector2d a(Draw(rng, inner_lo.x(), inner_hi.x()),
                            Draw(rng, inner_lo.y(), inner_hi.y()));
    const double apart = Draw(rng, min_apart, max_apart), angle = Draw(rng, -M_PI, M_PI);
    const Eigen::Vector2d b = a + apart * Eigen::Vector2d(std::cos(angle), std::sin(angle));
    if (inside(b)) return std::make_pair(a, b);
  }
  return std::nullopt;
}

}  // namespace forestmap::algorithms
