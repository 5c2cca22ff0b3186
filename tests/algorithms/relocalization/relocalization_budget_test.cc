// The index's and the search's budgets (index side) against truth: page-mapped build
// buffers, the sparse stands' larger per-tree triangle budget, when a search is decided, and
// the bitmap hits a pose needs before it is polished.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "algorithms/relocalization/map_index_internal.h"
#include "algorithms/relocalization/page_vector.h"
#include "algorithms/relocalization/search_budget.h"
#include "algorithms/relocalization/triangle_levels.h"

namespace forestmap::algorithms {
namespace {

std::vector<Eigen::Vector2d> UniformStand(int n, double extent, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, extent);
  std::vector<Eigen::Vector2d> points(n);
  for (auto& p : points) p = {u(rng), u(rng)};
  return points;
}

KdTree<float, 2> KdOf(const std::vector<Eigen::Vector2d>& points) {
  std::vector<KdTree<float, 2>::Point> xy;
  for (const auto& p : points) xy.push_back({static_cast<float>(p.x()), static_cast<float>(p.y())});
  return KdTree<float, 2>(std::move(xy));
}

TEST(PageVector, HoldsSmallAndPageMappedBlocksThroughGrowth) {
  PageVector<Triangle> triangles;
  std::vector<Triangle> truth;
  for (uint32_t i = 0; i < 200000; ++i) {  // 4.8 MB: the last blocks are mapped pages
    const Triangle t{{1.f * i, 2.f * i, 3.f * i}, {i, i + 1, i + 2}};
    triangles.push_back(t);
    truth.push_back(t);
  }
  ASSERT_EQ(triangles.size(), truth.size());
  for (size_t i = 0; i < truth.size(); i += 997) {
    EXPECT_EQ(triangles[i].vertex, truth[i].vertex);
    EXPECT_EQ(triangles[i].sides, truth[i].sides);
  }
  PageVector<Triangle>().swap(triangles);  // unmapped without a fault
  EXPECT_TRUE(triangles.empty());
}

TEST(SparseBudget, GrowsWithTheSquareOfTheSpacingUpToItsCap) {
  const SparseBudget sparse{5.0, 4.0};
  EXPECT_DOUBLE_EQ(sparse.Factor(2.0), 1.0);
  EXPECT_DOUBLE_EQ(sparse.Factor(5.0), 1.0);
  EXPECT_DOUBLE_EQ(sparse.Factor(7.5), 2.25);
  EXPECT_DOUBLE_EQ(sparse.Factor(10.0), 4.0);
  EXPECT_DOUBLE_EQ(sparse.Factor(40.0), 4.0);
  EXPECT_DOUBLE_EQ(SparseBudget{}.Factor(40.0), 1.0);  // off by default
}

// Mean triangles per tree of an index with these levels (each triangle counted once).
double TrianglesPerTree(const KdTree<float, 2>& kd, const std::vector<Eigen::Vector2d>& points,
                        const std::vector<uint8_t>& level, const TriangleLevels& levels) {
  size_t total = 0;
  for (const auto& band : EnumerateLevelled(kd, points, level, levels, 0, points.size())) {
    total += band.size();
  }
  return static_cast<double>(total) / points.size();
}

TEST(SparseBudget, ASparseStandKeepsLongerTrianglesWithinTheGrownBudget) {
  // A sparse stand (0.012 trees/m^2: 6th-neighbour spacing ~ 11 m) whose wanted level is cut by
  // a per-tree budget of 2 triangles.
  const std::vector<Eigen::Vector2d> points = UniformStand(1100, 300.0, 5);
  const KdTree<float, 2> kd = KdOf(points);
  TriangleLevels levels;
  levels.base_side = 1.25;
  levels.max_side = 30;
  levels.scale = 1.35;
  const SpacingCells cells(kd, 25.0, 1);
  const double cap = 2.0;
  const std::vector<uint8_t> plain = cells.Levels(kd, levels, cap);
  const SparseBudget sparse{5.0, 4.0};
  const std::vector<uint8_t> grown = cells.Levels(kd, levels, cap, sparse);
  int higher = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_GE(grown[i], plain[i]);
    higher += grown[i] > plain[i];
  }
  EXPECT_GT(higher, 500);
  const double before = TrianglesPerTree(kd, points, plain, levels);
  const double after = TrianglesPerTree(kd, points, grown, levels);
  EXPECT_LE(before, 1.5 * cap);
  EXPECT_GT(after, cap);  // the sparse stand uses more than the base budget ...
  EXPECT_LE(after, 1.5 * cap * sparse.max_factor);  // ... within the grown one (sampled cells)
}

LevelledQuery QueryOf(const std::vector<Eigen::Vector2d>& xy) {
  LevelledQuery q;
  q.xy = xy;
  q.z.assign(xy.size(), 0.0);
  q.dbh.assign(xy.size(), kUnknown);
  for (uint32_t i = 0; i < xy.size(); ++i) q.used.push_back(i);
  return q;
}

TEST(StrongInliers, AskNoMoreThanASmallQueryCanShowAndAsBeforeForLargeOnes) {
  const RelocalizerOptions options;
  for (int n = 3; n <= 60; ++n) {
    std::vector<Eigen::Vector2d> xy;
    for (int i = 0; i < n; ++i) xy.push_back({0.25 * i, 0.0});  // all within ratio_range
    const LevelledQuery q = QueryOf(xy);
    const int strong = StrongInliers(q, options);
    const int nearest = RatioTrees(q, options);
    EXPECT_GE(strong, options.min_inliers) << n;
    EXPECT_GE(strong, static_cast<int>(options.decisive_fraction * nearest)) << n;
    if (n >= 20) {  // unchanged: twice min_inliers or the decisive share
      EXPECT_EQ(strong, std::max(2 * options.min_inliers,
                                 static_cast<int>(options.decisive_fraction * nearest)))
          << n;
    } else if (n >= 10) {
      EXPECT_LE(strong, n - 3) << n;  // a view of 10-19 trees with 3 missed or false can decide
    }
  }
}

TEST(PolishHits, ARandomPoseInADenseStandRarelyPassesTheTruePoseAlways) {
  // 0.8 trees/m^2: a quarter of the 0.4 m bitmap is near a tree.
  const std::vector<Eigen::Vector2d> points = UniformStand(20000, 160.0, 7);
  std::vector<MapTree> trees;
  for (size_t i = 0; i < points.size(); ++i) {
    trees.push_back({static_cast<int64_t>(i), {points[i].x(), points[i].y(), kUnknown}, kUnknown});
  }
  const MapIndex index(trees);
  const MapIndexImpl& m = index.impl();
  const RelocalizerOptions options;
  // The query: the 30 trees nearest the sensor, in the sensor frame (the true pose: identity).
  const Eigen::Vector2d sensor = m.Xy(0);
  std::vector<Eigen::Vector2d> xy;
  for (size_t i = 0; i < points.size(); ++i) xy.push_back(m.Xy(static_cast<uint32_t>(i)) - sensor);
  std::sort(xy.begin(), xy.end(), [](const auto& a, const auto& b) { return a.norm() < b.norm(); });
  xy.resize(options.quick_score_trees);
  const LevelledQuery q = QueryOf(xy);
  auto hits = [&](const Rigid2& pose) {
    int count = 0;
    for (const auto& p : q.xy) {
      const Eigen::Vector2d at = pose(p);
      count += m.occupancy->Near(at.x(), at.y());
    }
    return count;
  };
  Rigid2 truth;
  truth.translation = sensor;
  const int base = 3;
  EXPECT_GE(hits(truth), PolishHits(m, q, truth, base, options));
  EXPECT_GT(PolishHits(m, q, truth, base, options), 10);  // well above base in this stand
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> along(20.0, 140.0), turn(-M_PI, M_PI);
  int passed = 0, passed_base = 0;
  const int tries = 2000;
  for (int k = 0; k < tries; ++k) {
    Rigid2 pose;
    pose.yaw = turn(rng);
    pose.translation = Eigen::Vector2d(along(rng), along(rng)) - m.origin;
    passed += hits(pose) >= PolishHits(m, q, pose, base, options);
    passed_base += hits(pose) >= base;
  }
  EXPECT_LT(passed, tries / 50);           // under 2% of random poses are polished
  EXPECT_GT(passed_base, tries * 9 / 10);  // against 90% with the fixed base
}

TEST(PolishHits, IsTheBaseWhereTheStandIsSparse) {
  const std::vector<Eigen::Vector2d> points = UniformStand(500, 200.0, 9);
  std::vector<MapTree> trees;
  for (size_t i = 0; i < points.size(); ++i) {
    trees.push_back({static_cast<int64_t>(i), {points[i].x(), points[i].y(), kUnknown}, kUnknown});
  }
  const MapIndex index(trees);
  std::vector<Eigen::Vector2d> xy;
  for (int i = 0; i < 30; ++i) xy.push_back({0.5 * i, 0.0});
  Rigid2 pose;
  pose.translation = index.impl().Xy(0);
  EXPECT_EQ(PolishHits(index.impl(), QueryOf(xy), pose, 7, RelocalizerOptions{}), 7);
}

}  // namespace
}  // namespace forestmap::algorithms
