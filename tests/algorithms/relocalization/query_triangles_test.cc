// The order in which a query's triangles are looked up (query_triangles.h KeepSpread) against
// truth: no seed tree dominates the first triangles, nothing is lost or duplicated, and in a
// dense stand whose nearest detections include false stems, the first triangles looked up hold
// triangles of three true trees, which nearest-first alone did not.
#include "algorithms/relocalization/query_triangles.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/map_index_internal.h"

namespace forestmap::algorithms {
namespace {

QueryTriangle Tri(uint32_t a, uint32_t b, uint32_t c, int level = 0) {
  return {Triangle{{1.f, 2.f, 3.f}, {a, b, c}}, level};
}

std::vector<int> Uses(const std::vector<QueryTriangle>& triangles, size_t first) {
  std::vector<int> uses;
  for (size_t t = 0; t < std::min(first, triangles.size()); ++t) {
    for (uint32_t v : triangles[t].triangle.vertex) {
      if (uses.size() <= v) uses.resize(v + 1, 0);
      ++uses[v];
    }
  }
  return uses;
}

TEST(KeepSpread, LimitsEachSeedPerRoundAndKeepsNearestFirstWithinIt) {
  // Seed 0 (a false stem beside the sensor) is a vertex of the 20 nearest triangles; the
  // triangles without it come after them.
  std::vector<QueryTriangle> triangles;
  for (uint32_t i = 1; i <= 20; ++i) triangles.push_back(Tri(0, i, i + 1));
  for (uint32_t i = 30; i < 40; ++i) triangles.push_back(Tri(i, i + 1, i + 2));
  std::vector<QueryTriangle> spread = triangles;
  KeepSpread(spread, 12, 4, 16);
  ASSERT_EQ(spread.size(), 12u);
  // Round one: the 4 nearest with seed 0, then the nearest whose seeds all had fewer than 4.
  EXPECT_EQ(Uses(spread, 12)[0], 4);
  for (int t = 0; t < 4; ++t) EXPECT_EQ(spread[t].triangle.vertex, triangles[t].triangle.vertex);
  EXPECT_EQ(spread[4].triangle.vertex, (std::array<uint32_t, 3>{30, 31, 32}));
  for (int v : Uses(spread, 12)) EXPECT_LE(v, 4);
}

TEST(KeepSpread, KeepsEveryTriangleOnceWhenUnderTheLimit) {
  std::vector<QueryTriangle> triangles;
  for (uint32_t i = 0; i < 30; ++i) triangles.push_back(Tri(0, 1 + i % 3, 5 + i, i % 2));
  std::vector<QueryTriangle> spread = triangles;
  KeepSpread(spread, 100, 4, 16);
  ASSERT_EQ(spread.size(), triangles.size());
  auto key = [](const QueryTriangle& t) { return std::make_pair(t.triangle.vertex, t.level); };
  std::vector<std::pair<std::array<uint32_t, 3>, int>> a, b;
  for (const auto& t : triangles) a.push_back(key(t));
  for (const auto& t : spread) b.push_back(key(t));
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
  // Rounds of 4, 8, 16: seed 0 is in every triangle, so 4, 4 more, 8 more, then the rest.
  EXPECT_EQ(spread[3].triangle.vertex, triangles[3].triangle.vertex);
  EXPECT_EQ(Uses(spread, 4)[0], 4);
  KeepSpread(spread, 5, 0, 0);  // caps below 1 act as 1: still terminates, keeps 5
  EXPECT_EQ(spread.size(), 5u);
}

// A dense stand (0.47 trees/m^2, like boreasNS): the map, and a view of it from the centre
// with 30% of the trees missed and 12 false stems within 3 m of the sensor.
TEST(KeepSpread, DenseViewWithFalseStemsNearTheSensorGetsTrueTrianglesEarly) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-30, 30), near(-2.1, 2.1), unit(0, 1);
  std::vector<MapTree> map;
  for (int i = 0; i < 1700; ++i) map.push_back({i, {u(rng), u(rng), 0}, 0.2});
  const MapIndex index(map);
  std::vector<std::pair<double, std::pair<Eigen::Vector2d, bool>>> seen;  // range, (xy, true)
  for (const MapTree& t : map) {
    const Eigen::Vector2d xy = t.position.head<2>();
    if (xy.norm() <= 15 && unit(rng) >= 0.3) seen.push_back({xy.norm(), {xy, true}});
  }
  for (int i = 0; i < 12; ++i) {
    const Eigen::Vector2d xy(near(rng), near(rng));
    seen.push_back({xy.norm(), {xy, false}});
  }
  std::sort(seen.begin(), seen.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Eigen::Vector2d> seeds;
  std::vector<bool> real;
  for (size_t i = 0; i < std::min<size_t>(40, seen.size()); ++i) {
    seeds.push_back(seen[i].second.first);
    real.push_back(seen[i].second.second);
  }
  const std::vector<QueryTriangle> all =
      QueryTriangles(seeds, index.impl(), QuerySide(seeds, index.impl()), 0.2);
  ASSERT_GT(all.size(), 200u);
  auto true_ones = [&](const std::vector<QueryTriangle>& triangles, size_t first) {
    int count = 0;
    for (size_t t = 0; t < std::min(first, triangles.size()); ++t) {
      const auto& v = triangles[t].triangle.vertex;
      count += real[v[0]] && real[v[1]] && real[v[2]];
    }
    return count;
  };
  std::vector<QueryTriangle> spread = all;
  KeepSpread(spread, 200, kFirstTrianglesPerSeed, kMaxTrianglesPerSeed);
  ASSERT_EQ(spread.size(), 200u);
  // The first 30 looked up (a dense stand's search budget runs out after a few tens).
  const int before = true_ones(all, 30), after = true_ones(spread, 30);
  EXPECT_LE(before, 1);  // nearest first: the false stems' triangles (0 here)
  EXPECT_GE(after, 3);   // 5 here
  EXPECT_GT(after, before);
}

}  // namespace
}  // namespace forestmap::algorithms
