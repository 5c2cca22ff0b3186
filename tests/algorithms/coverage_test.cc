// A map's coverage against truth: the Delaunay triangulation against brute force (every
// circumcircle empty), polygons against their area, the coverage derived from a stand's trees
// against the stand's true extent (a half-plane, a clearing, two stands apart), and its raster
// against the polygons.
#include "algorithms/relocalization/coverage.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "algorithms/core/delaunay.h"
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

double TriangleArea(const std::vector<Eigen::Vector2d>& p, const std::array<uint32_t, 3>& t) {
  return SignedArea({p[t[0]], p[t[1]], p[t[2]]});
}

TEST(Delaunay, EveryCircumcircleIsEmptyAndTheTrianglesTileTheHull) {
  // The predicates are exact on coordinates rounded to a millimetre: points on that grid are
  // triangulated exactly (elsewhere a nearly cocircular point may lie a rounding inside).
  std::vector<Eigen::Vector2d> points = Scatter(400, 100, 60, 1);
  for (Eigen::Vector2d& p : points) p = (p * 1000).array().round() / 1000;
  const Triangulation tri = Delaunay(points);
  // Euler: a triangulation of n points with h on the hull has 2n - 2 - h triangles; the hull of
  // 400 uniform points has about 20.
  EXPECT_GE(tri.triangles.size(), 2 * 400 - 2 - 40u);
  EXPECT_LE(tri.triangles.size(), 2 * 400 - 2 - 3u);
  double area = 0;
  for (size_t t = 0; t < tri.triangles.size(); ++t) {
    const auto& v = tri.triangles[t];
    ASSERT_GT(TriangleArea(points, v), 0) << "triangle " << t << " not counter-clockwise";
    area += TriangleArea(points, v);
    const double r = Circumradius(points[v[0]], points[v[1]], points[v[2]]);
    // The circumcentre, and no point strictly inside the circle (brute force).
    const Eigen::Vector2d a = points[v[0]], b = points[v[1]], c = points[v[2]];
    const double d =
        2 * (a.x() * (b.y() - c.y()) + b.x() * (c.y() - a.y()) + c.x() * (a.y() - b.y()));
    const Eigen::Vector2d centre(
        (a.squaredNorm() * (b.y() - c.y()) + b.squaredNorm() * (c.y() - a.y()) +
         c.squaredNorm() * (a.y() - b.y())) /
            d,
        (a.squaredNorm() * (c.x() - b.x()) + b.squaredNorm() * (a.x() - c.x()) +
         c.squaredNorm() * (b.x() - a.x())) /
            d);
    for (size_t i = 0; i < points.size(); ++i) {
      ASSERT_GE((points[i] - centre).norm(), r * (1 - 1e-9)) << "point " << i << " in " << t;
    }
    for (int i = 0; i < 3; ++i) {  // neighbours share the edge, reversed
      const int32_t nb = tri.neighbours[t][i];
      if (nb < 0) continue;
      const uint32_t from = v[(i + 1) % 3], to = v[(i + 2) % 3];
      const auto& w = tri.neighbours[nb];
      EXPECT_TRUE(std::find(w.begin(), w.end(), static_cast<int32_t>(t)) != w.end());
      const auto& u = tri.triangles[nb];
      EXPECT_TRUE(std::find(u.begin(), u.end(), from) != u.end());
      EXPECT_TRUE(std::find(u.begin(), u.end(), to) != u.end());
    }
  }
  // The triangles tile the convex hull, which for 400 uniform points fills most of the box.
  EXPECT_GT(area, 0.93 * 100 * 60);
  EXPECT_LE(area, 100 * 60 * (1 + 1e-9));
}

TEST(Delaunay, APlantedGridOfCocircularPointsAndDuplicatesIsTriangulated) {
  std::vector<Eigen::Vector2d> grid;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 15; ++j) grid.push_back({3.0 * i, 2.5 * j});
  }
  grid.push_back(grid[17]);  // a tree surveyed twice
  const Triangulation tri = Delaunay(grid);
  // 300 distinct points on a 20 x 15 grid: 2 x 19 x 14 triangles exactly covering the grid.
  EXPECT_EQ(tri.triangles.size(), 2u * 19 * 14);
  double area = 0;
  for (const auto& t : tri.triangles) {
    EXPECT_GT(TriangleArea(grid, t), 0);
    EXPECT_NE(t[0], 300u);
    EXPECT_NE(t[1], 300u);
    EXPECT_NE(t[2], 300u);
    area += TriangleArea(grid, t);
  }
  EXPECT_NEAR(area, 57.0 * 35.0, 1e-6);
  EXPECT_TRUE(Delaunay({{0, 0}, {1, 1}, {2, 2}, {3, 3}}).triangles.empty());  // collinear
  EXPECT_THROW(Delaunay({{0, 0}, {1, NAN}, {2, 0}}), std::invalid_argument);
}

TEST(Polygon, AreaAndContainmentWithAHole) {
  const Polygon square{{{0, 0}, {10, 0}, {10, 10}, {0, 10}}, {{{4, 4}, {4, 6}, {6, 6}, {6, 4}}}};
  EXPECT_DOUBLE_EQ(Area(square), 96.0);
  EXPECT_TRUE(Contains(square, Eigen::Vector2d(1, 1)));
  EXPECT_FALSE(Contains(square, Eigen::Vector2d(5, 5)));
  EXPECT_FALSE(Contains(square, Eigen::Vector2d(11, 5)));
  EXPECT_THROW(CheckPolygons({{{{0, 0}, {1, 0}}, {}}}), std::invalid_argument);
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
