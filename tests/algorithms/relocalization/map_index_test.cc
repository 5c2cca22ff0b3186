// The relocalizer's index structures against brute force: the triangle table's key lookup, the
// occupancy grid's "is a tree within r?", and the Poisson tail behind the significance test.
#include "algorithms/relocalization/map_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "algorithms/relocalization/occupancy_grid.h"
#include "algorithms/relocalization/pose_search.h"
#include "algorithms/relocalization/triangle_levels.h"
#include "algorithms/relocalization/triangle_table.h"

namespace forestmap::algorithms {
namespace {

std::vector<Eigen::Vector2d> RandomPoints(int n, double extent, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Eigen::Vector2d> points(n);
  for (auto& p : points) p = {u(rng), u(rng)};
  return points;
}

TEST(TriangleTable, FindsExactlyTheTrianglesWithinTheToleranceOfEachSide) {
  const std::vector<Eigen::Vector2d> points = RandomPoints(400, 30.0, 1);
  TriangleOptions options;
  options.max_side = 6.0;
  std::vector<std::vector<uint32_t>> neighbours(points.size());
  for (uint32_t i = 0; i < points.size(); ++i) {
    for (uint32_t j = 0; j < points.size(); ++j) {
      if (i != j && (points[i] - points[j]).norm() <= options.max_side) neighbours[i].push_back(j);
    }
  }
  const std::vector<Triangle> triangles = EnumerateTriangles(points, neighbours, options);
  ASSERT_GT(triangles.size(), 1000u);
  const TriangleTable table(triangles, points, options.max_side);
  EXPECT_EQ(table.size(), triangles.size());

  std::mt19937 rng(2);
  std::uniform_int_distribution<size_t> pick(0, triangles.size() - 1);
  for (float tolerance : {0.05f, 0.1f, 0.2f, 0.5f}) {
    for (int trial = 0; trial < 50; ++trial) {
      std::array<float, 3> query = triangles[pick(rng)].sides;
      query[2] += 0.03f;  // not exactly a stored key
      // Sides are stored in millimetres: keys within 1 mm of the boundary may go either way.
      std::multiset<std::array<float, 2>> inside, within_boundary, found;
      for (const Triangle& t : triangles) {
        float worst = 0;
        for (int d = 0; d < 3; ++d) worst = std::max(worst, std::abs(t.sides[d] - query[d]));
        const TriangleFrame f =
            FrameOf(points[t.vertex[0]], points[t.vertex[1]], points[t.vertex[2]]);
        if (worst <= tolerance - 1e-3f) inside.insert({f.cx, f.cy});
        if (worst <= tolerance + 1e-3f) within_boundary.insert({f.cx, f.cy});
      }
      table.ForEachMatch(query, tolerance, [&](const IndexedTriangle& t) {
        found.insert({t.cx, t.cy});
      });
      for (const auto& c : inside) EXPECT_TRUE(found.count(c)) << "tolerance " << tolerance;
      for (const auto& c : found)
        EXPECT_TRUE(within_boundary.count(c)) << "tolerance " << tolerance;
      EXPECT_GE(table.CandidateCount(query, tolerance), found.size());
    }
  }
}

TEST(TriangleTable, FrameKeepsCentroidHeadingAndOrientation) {
  const std::vector<Eigen::Vector2d> points = {{0, 0}, {4, 0}, {1, 2}};
  const TriangleFrame f = FrameOf(points[0], points[1], points[2]);
  EXPECT_NEAR(f.cx, 5.0 / 3, 1e-6);
  EXPECT_NEAR(f.cy, 2.0 / 3, 1e-6);
  EXPECT_NEAR(f.cos_heading, 1.0, 1e-6);
  EXPECT_NEAR(f.sin_heading, 0.0, 1e-6);
  EXPECT_EQ(f.turn, 1);  // counter-clockwise
  EXPECT_EQ(FrameOf(points[0], points[2], points[1]).turn, -1);
  EXPECT_EQ(FrameOf({0, 0}, {4, 0}, {2, 0.01}).turn, 0);  // nearly collinear
}

TEST(TriangleLevels, SidesGrowGeometricallyAndSpacingPicksTheNearestLevel) {
  TriangleLevels levels;
  levels.base_side = 1.75;
  levels.scale = 1.5;
  ASSERT_EQ(levels.count(), 10);  // 1.75 m ... 28 m, then 30 m
  EXPECT_DOUBLE_EQ(levels.Side(levels.count() - 1), 30.0);
  for (int l = 1; l < levels.count(); ++l) EXPECT_GT(levels.Side(l), levels.Side(l - 1));
  EXPECT_EQ(levels.LevelFor(0.1), levels.LevelFor(3.5 / 1.5));  // the floor: 3.5 m
  EXPECT_NEAR(levels.Side(levels.LevelFor(10.0)), 15.0, 15.0 * 0.2);
  EXPECT_EQ(levels.LevelFor(1000.0), levels.count() - 1);
  // A square grid of 2 m: the 6th nearest neighbour is 2 sqrt(2) m away (inside the grid).
  std::vector<Eigen::Vector2d> grid;
  for (int i = -5; i <= 5; ++i) {
    for (int j = -5; j <= 5; ++j) grid.push_back({2.0 * i, 2.0 * j});
  }
  std::sort(grid.begin(), grid.end(),
            [](const auto& a, const auto& b) { return a.norm() < b.norm(); });
  EXPECT_NEAR(QuerySpacing(grid, 9), 2 * std::sqrt(2.0), 1e-9);
}

TEST(TriangleLevels, EveryTriangleIsFiledOnceInTheBandOfItsLongestSide) {
  std::vector<Eigen::Vector2d> points = RandomPoints(300, 40.0, 3);
  std::vector<KdTree<float, 2>::Point> xy;
  for (const auto& p : points) xy.push_back({static_cast<float>(p.x()), static_cast<float>(p.y())});
  const KdTree<float, 2> kd(std::move(xy));
  TriangleLevels levels;
  levels.base_side = 2.0;
  levels.max_side = 8.0;
  std::vector<uint8_t> level(points.size());
  for (size_t i = 0; i < points.size(); ++i) level[i] = points[i].x() < 0 ? 1 : 2;  // 2.8, 4 m
  const auto bands = EnumerateLevelled(kd, points, level, levels, 0, points.size());
  size_t total = 0;
  for (size_t band = 0; band < bands.size(); ++band) {
    for (const Triangle& t : bands[band]) {
      const int lowest = std::min({level[t.vertex[0]], level[t.vertex[1]], level[t.vertex[2]]});
      EXPECT_LE(t.sides[2], levels.Side(lowest) + 1e-4);
      EXPECT_LE(t.sides[2], levels.Side(static_cast<int>(band)) + 1e-4);
      if (band > 0) {
        EXPECT_GT(t.sides[2], levels.Side(static_cast<int>(band) - 1) - 1e-4);
      }
      ++total;
    }
  }
  // Brute force: every triple whose sides fit the lowest level of its points.
  size_t brute = 0;
  for (uint32_t i = 0; i < points.size(); ++i) {
    for (uint32_t j = i + 1; j < points.size(); ++j) {
      for (uint32_t k = j + 1; k < points.size(); ++k) {
        const Triangle t = MakeTriangle(points, i, j, k);
        const double side = levels.Side(std::min({level[i], level[j], level[k]}));
        brute += t.sides[0] >= levels.min_side && t.sides[2] <= side;
      }
    }
  }
  EXPECT_EQ(total, brute);
  EXPECT_GT(total, 100u);
}

TEST(OccupancyGrid, AgreesWithBruteForceAwayFromTheBoundary) {
  // Two clusters 5 km apart: the tiles are found through the sparse hash, not a directory.
  std::vector<Eigen::Vector2d> points = RandomPoints(300, 20.0, 3);
  for (const Eigen::Vector2d& p : RandomPoints(300, 20.0, 4))
    points.push_back(p + Eigen::Vector2d(5000, -3000));
  constexpr double kRadius = 0.4, kResolution = 0.2;
  const double fuzz = kResolution * std::sqrt(0.5);  // half a cell diagonal
  for (const auto& cloud :
       {std::vector<Eigen::Vector2d>(points.begin(), points.begin() + 300), points}) {
    const OccupancyGrid grid(cloud, kRadius, kResolution);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-22.0, 22.0);
    int checked = 0, near = 0;
    for (int trial = 0; trial < 20000; ++trial) {
      const Eigen::Vector2d q = cloud[trial % cloud.size()] + Eigen::Vector2d(u(rng), u(rng)) / 20;
      double nearest = INFINITY;
      for (const Eigen::Vector2d& p : cloud) nearest = std::min(nearest, (p - q).norm());
      if (std::abs(nearest - kRadius) < fuzz) continue;
      ++checked;
      near += nearest < kRadius;
      EXPECT_EQ(grid.Near(q.x(), q.y()), nearest < kRadius) << q.transpose();
    }
    EXPECT_GT(checked, 10000);
    EXPECT_GT(near, 1000);
    EXPECT_FALSE(grid.Near(1e6, 1e6));
    // 300 points in 40 x 40 m: about 1 - exp(-density pi r^2) of the area is near a tree.
    EXPECT_GT(grid.occupied_fraction(), 0.0);
    EXPECT_LT(grid.occupied_fraction(), 0.2);
  }
}

// Issue 15: a tree at x = 1e308 made the index build index tiles_[-1] and take the server down.
// Coordinates the index cannot represent are an error, never a crash.
TEST(OccupancyGrid, RejectsPointsBeyondItsCellRange) {
  for (double far : {1e308, 1e15, -3e13}) {
    const std::vector<Eigen::Vector2d> points = {{0, 0}, {3, 0}, {far, 1}};
    EXPECT_THROW(OccupancyGrid(points, 0.4, 0.2), std::invalid_argument) << far;
  }
  const std::vector<Eigen::Vector2d> nan_point = {{0, 0}, {NAN, 1}};
  EXPECT_THROW(OccupancyGrid(nan_point, 0.4, 0.2), std::invalid_argument);
}

TEST(MapIndex, RejectsTreesBeyondItsRangeInsteadOfCrashing) {
  auto trees = [](double x, double y) {
    std::vector<MapTree> out(4);
    out[1].position = {3, 0, NAN};
    out[2].position = {0, 4, NAN};
    out[3].position = {x, y, NAN};
    out[0].position.z() = NAN;
    return out;
  };
  for (auto [x, y] :
       {std::pair{1e308, 1.0}, {1.0, -1e45}, {2e9, 0.0}, {NAN, 0.0}, {INFINITY, 0.0}}) {
    try {
      MapIndex index(trees(x, y));
      ADD_FAILURE() << "no error for a tree at (" << x << ", " << y << ")";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("trees[3]"), std::string::npos) << e.what();
    }
  }
  std::vector<MapTree> tall = trees(5, 5);
  tall[3].position.z() = 1e300;
  EXPECT_THROW(MapIndex index(tall), std::invalid_argument);
  const MapIndex wide(trees(9.9e6, -9.9e6));  // a large but valid local frame still builds
  EXPECT_EQ(wide.size(), 4u);
}

TEST(PoissonTail, MatchesDirectSums) {
  for (double lambda : {0.05, 0.7, 3.0, 20.0}) {
    double cdf = 0, term = std::exp(-lambda);
    for (int k = 0; k < 60; ++k) {
      EXPECT_NEAR(PoissonTail(k, lambda), 1.0 - cdf, 1e-9 + 1e-6 * (1.0 - cdf))
          << k << " " << lambda;
      cdf += term;
      term *= lambda / (k + 1);
    }
  }
  EXPECT_EQ(PoissonTail(0, 3.0), 1.0);
  EXPECT_EQ(PoissonTail(5, 0.0), 0.0);
  EXPECT_NEAR(PoissonTail(7, 0.7), 8.9e-6, 0.2e-6);  // the sparse wrong-forest case
}

}  // namespace
}  // namespace forestmap::algorithms
