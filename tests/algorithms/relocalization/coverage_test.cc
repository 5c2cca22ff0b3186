// A map's coverage against truth: the coverage derived from a stand's trees against the stand's
// true extent (a half-plane, a clearing, two stands apart), and its raster against the polygons.
#include "algorithms/relocalization/coverage.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "algorithms/core/polygon.h"

namespace forestmap::algorithms {
namespace {

// Uniform random points in [0, width] x [0, height], none within `clear` of `hole` (m).
std::vector<Eigen::Vector2d> Scatter(int n, double width, double height, unsigned seed,
                                     const Eigen::Vector2d& hole = {-1e9, -1e9}, double clear = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(0, width), y(0, height);
  std::vector<Eigen::Vector2d> points;
  while (static_cast<int>(points.size()) < n) {
    const Eigen::Vector2d p(x(rng), y(rng));
    if ((p - hole).norm() >= clear) points.push_back(p);
  }
  return points;
}

// The coverage of a stand's trees against the stand's true extent.
std::vector<Polygon> Derived(const std::vector<Eigen::Vector2d>& points, float spacing) {
  return DeriveCoverage(points, std::vector<float>(points.size(), spacing), CoverageOptions{});
}

// 0.05 trees/m^2 (a 6th-neighbour spacing of about 6 m).
constexpr double kDensity = 0.05;
const float kSpacing = static_cast<float>(std::sqrt(5.5 / (M_PI * kDensity)));

TEST(Coverage, DerivedFromAStandIsItsExtentWithoutHoles) {
  const std::vector<Eigen::Vector2d> stand =
      Scatter(static_cast<int>(kDensity * 200 * 120), 200, 120, 2);
  const std::vector<Polygon> coverage = Derived(stand, kSpacing);
  ASSERT_EQ(coverage.size(), 1u);
  EXPECT_TRUE(coverage[0].holes.empty());
  // The boundary runs through the outermost trees: about half a spacing inside the true edge.
  EXPECT_GT(Area(coverage[0]), 0.9 * 200 * 120);
  EXPECT_LE(Area(coverage[0]), 200 * 120);
}

TEST(Coverage, AClearingWiderThanTwoSpacingsIsAHoleAndFarStandsStayApart) {
  const Eigen::Vector2d clearing(100, 60);
  std::vector<Eigen::Vector2d> trees =
      Scatter(static_cast<int>(kDensity * 200 * 120), 200, 120, 3, clearing, 4 * kSpacing);
  for (const Eigen::Vector2d& p : Scatter(200, 60, 60, 4)) {
    trees.push_back(p + Eigen::Vector2d(300, 0));  // a second stand 100 m away
  }
  const std::vector<Polygon> coverage = Derived(trees, kSpacing);
  ASSERT_EQ(coverage.size(), 2u);
  EXPECT_FALSE(Contains(coverage, clearing));
  EXPECT_FALSE(Contains(coverage, Eigen::Vector2d(250, 30)));  // between the stands
  EXPECT_TRUE(Contains(coverage, Eigen::Vector2d(330, 30)));
  EXPECT_TRUE(Contains(coverage, Eigen::Vector2d(50, 60)));
  int holes = 0;
  for (const Polygon& p : coverage) holes += static_cast<int>(p.holes.size());
  EXPECT_EQ(holes, 1);
}

// Distance (m) from p to the nearest edge of any ring of `shape`.
double DistanceToEdges(const std::vector<Polygon>& shape, const Eigen::Vector2d& p) {
  double nearest = INFINITY;
  auto ring_distance = [&](const Ring& ring) {
    for (size_t a = 0, b = ring.size() - 1; a < ring.size(); b = a++) {
      const Eigen::Vector2d e = ring[a] - ring[b];
      const double t = std::clamp((p - ring[b]).dot(e) / e.squaredNorm(), 0.0, 1.0);
      nearest = std::min(nearest, (ring[b] + t * e - p).norm());
    }
  };
  for (const Polygon& poly : shape) {
    ring_distance(poly.outer);
    for (const Ring& hole : poly.holes) ring_distance(hole);
  }
  return nearest;
}

TEST(Coverage, TheRasterAgreesWithThePolygonsAwayFromTheirBoundary) {
  const std::vector<Polygon> shape{
      {{{0, 0}, {80, 0}, {80, 50}, {0, 50}}, {{{20, 20}, {20, 30}, {40, 30}, {40, 20}}}},
      {{{100, 0}, {130, 0}, {115, 40}}, {}}};
  const std::vector<Eigen::Vector2d> lone_tree = {{200, 200}};
  const CoverageGrid grid(shape, lone_tree, 0.4, 0.5);
  EXPECT_NEAR(grid.area(), 80 * 50 - 200 + 600 + M_PI * 0.75 * 0.75, 30.0);
  EXPECT_NEAR(grid.perimeter(), 260 + 60 + 30 + 2 * std::hypot(15, 40), 0.3 * 400);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> x(-10, 210), y(-10, 210);
  int checked = 0;
  for (int k = 0; k < 20000; ++k) {
    const Eigen::Vector2d p(x(rng), y(rng));
    if ((p - lone_tree[0]).norm() <= 0.4) {
      EXPECT_TRUE(grid.Covered(p.x(), p.y()));
    }
    if ((p - lone_tree[0]).norm() < 1.5) continue;
    if (DistanceToEdges(shape, p) < 0.71) continue;  // within a cell diagonal: either is right
    ++checked;
    ASSERT_EQ(grid.Covered(p.x(), p.y()), Contains(shape, p)) << p.transpose();
  }
  EXPECT_GT(checked, 19000);
  EXPECT_NEAR(grid.CoveredShare(0, 0, 16), 1.0, 1e-9);
  EXPECT_NEAR(grid.CoveredShare(72, 10, 16), 0.5, 0.05);
}

}  // namespace
}  // namespace forestmap::algorithms
