// algorithms/core: the k-d tree wrapper against brute force, WrapAngle at its boundaries, and the
// shared helpers (Require, ParallelFor).

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "algorithms/core/check.h"
#include "algorithms/core/geometry.h"
#include "algorithms/core/kdtree.h"
#include "algorithms/core/parallel.h"

namespace forestmap::algorithms {
namespace {

using Tree2 = KdTree<double, 2>;

std::vector<Tree2::Point> RandomPoints(size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-50.0, 50.0);
  std::vector<Tree2::Point> points(n);
  for (auto& p : points) p = {u(rng), u(rng)};
  return points;
}

double Distance2(const Tree2::Point& a, const Tree2::Point& b) {
  return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]);
}

// Squared distances from `query` to every point, ascending.
std::vector<double> BruteForce(const std::vector<Tree2::Point>& points, const Tree2::Point& query) {
  std::vector<double> d2;
  for (const auto& p : points) d2.push_back(Distance2(p, query));
  std::sort(d2.begin(), d2.end());
  return d2;
}

TEST(KdTree, NearestKnnAndRadiusMatchBruteForce) {
  const std::vector<Tree2::Point> points = RandomPoints(2000, 7);
  const Tree2 tree(points);
  const std::vector<Tree2::Point> queries = RandomPoints(200, 8);
  for (const auto& query : queries) {
    const std::vector<double> truth = BruteForce(points, query);
    const auto [nearest, nearest_d2] = tree.Nearest(query);
    ASSERT_GE(nearest, 0);
    EXPECT_DOUBLE_EQ(nearest_d2, truth[0]);
    EXPECT_DOUBLE_EQ(Distance2(points[nearest], query), truth[0]);

    const auto knn = tree.Knn(query, 10);
    ASSERT_EQ(knn.size(), 10u);
    for (size_t i = 0; i < knn.size(); ++i) {
      EXPECT_DOUBLE_EQ(knn[i].second, truth[i]) << "neighbour " << i;
      EXPECT_DOUBLE_EQ(Distance2(points[knn[i].first], query), knn[i].second);
    }

    constexpr double kRadius = 4.0;  // m
    std::vector<std::pair<uint32_t, double>> within;
    tree.Radius(query, kRadius, within);
    const size_t expected = std::count_if(truth.begin(), truth.end(),
                                          [](double d2) { return d2 <= kRadius * kRadius; });
    EXPECT_EQ(within.size(), expected);
    for (const auto& [index, d2] : within) EXPECT_LE(Distance2(points[index], query), 16.0);
  }
}

TEST(KdTree, EmptyAndSmallTreesAnswerWithoutCrashing) {
  const Tree2 empty({});
  EXPECT_EQ(empty.Nearest({0, 0}).first, -1);
  EXPECT_TRUE(empty.Knn({0, 0}, 5).empty());
  std::vector<std::pair<uint32_t, double>> within{{1, 1.0}};
  empty.Radius({0, 0}, 10.0, within);
  EXPECT_TRUE(within.empty());

  const Tree2 two({{0, 0}, {3, 4}});
  const auto knn = two.Knn({0, 0}, 5);  // more than there are: all of them
  ASSERT_EQ(knn.size(), 2u);
  EXPECT_DOUBLE_EQ(knn[1].second, 25.0);
}

TEST(WrapAngle, ReturnsTheHalfOpenIntervalMinusPiExclusivePiInclusive) {
  EXPECT_DOUBLE_EQ(WrapAngle(M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(-M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(3 * M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(0.0), 0.0);
  EXPECT_NEAR(WrapAngle(2 * M_PI), 0.0, 1e-12);
  EXPECT_NEAR(WrapAngle(-M_PI + 1e-9), -M_PI + 1e-9, 1e-12);
  EXPECT_NEAR(WrapAngle(M_PI + 0.5), -M_PI + 0.5, 1e-12);
  EXPECT_NEAR(WrapAngle(-7.0), -7.0 + 2 * M_PI, 1e-12);
  for (double a = -20.0; a <= 20.0; a += 0.01) {
    const double w = WrapAngle(a);
    EXPECT_GT(w, -M_PI);
    EXPECT_LE(w, M_PI);
    EXPECT_NEAR(std::remainder(w - a, 2 * M_PI), 0.0, 1e-9) << a;
  }
}

TEST(Require, ThrowsInvalidArgumentNamingWhatAndTheValue) {
  EXPECT_NO_THROW(Require(true, "x must be > 0 m", -1.0));
  try {
    Require(false, "x must be > 0 m", -1.5);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "x must be > 0 m (got -1.5)");
  }
  EXPECT_THROW(Require(false, "plain"), std::invalid_argument);
}

TEST(ParallelFor, CoversEveryIndexOnceInContiguousChunks) {
  for (int chunks : {1, 2, 3, 7}) {
    std::vector<std::atomic<int>> hits(1001);
    ParallelFor(hits.size(), chunks, [&](int, size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) ++hits[i];
    });
    for (size_t i = 0; i < hits.size(); ++i) ASSERT_EQ(hits[i].load(), 1) << chunks << " " << i;
  }
}

}  // namespace
}  // namespace forestmap::algorithms
