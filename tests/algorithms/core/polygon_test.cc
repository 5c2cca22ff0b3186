// algorithms/core polygons and the Delaunay triangulation against truth: every circumcircle empty
// (brute force), the triangles tiling the hull, a planted grid of cocircular points and
// duplicates, polygon area and containment with a hole.
#include "algorithms/core/polygon.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "algorithms/core/delaunay.h"

namespace forestmap::algorithms {
namespace {

// Uniform random points in [0, width] x [0, height] (m).
std::vector<Eigen::Vector2d> Scatter(int n, double width, double height, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(0, width), y(0, height);
  std::vector<Eigen::Vector2d> points;
  while (static_cast<int>(points.size()) < n) {
    points.emplace_back(x(rng), y(rng));
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

}  // namespace
}  // namespace forestmap::algorithms
