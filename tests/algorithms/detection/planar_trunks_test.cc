// 2-D trunk detection on ray-cast planar scans of circular trunks.
#include "algorithms/detection/planar_trunks.h"

#include <gtest/gtest.h>

#include <random>

namespace forestmap::algorithms {
namespace {

struct Trunk {
  double x, y, radius;
};

// 1081 beams over 270 degrees, like a Hokuyo UTM-30LX, in a square room of walls 8 m away.
PlanarScan Cast(const std::vector<Trunk>& trunks, double noise_sd, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_sd);
  PlanarScan scan;
  for (int i = 0; i < 1081; ++i) {
    const double a = -0.75 * M_PI + i * (1.5 * M_PI / 1080);
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    double best = 8.0 / std::max(std::abs(d.x()), std::abs(d.y()));  // square room, 8 m
    for (const Trunk& t : trunks) {
      const Eigen::Vector2d c(t.x, t.y);
      const double b = d.dot(c), disc = b * b - c.squaredNorm() + t.radius * t.radius;
      if (disc >= 0 && b - std::sqrt(disc) > 0) best = std::min(best, b - std::sqrt(disc));
    }
    scan.angles.push_back(static_cast<float>(a));
    scan.ranges.push_back(static_cast<float>(best + noise(rng)));
  }
  return scan;
}

TEST(PlanarTrunksTest, FindsTrunksAndRejectsWalls) {
  const std::vector<Trunk> truth{{3, 0.5, 0.15}, {2, -3, 0.2}, {-1.5, 4, 0.12}, {5, 2.5, 0.25}};
  const PlanarTrunkResult result = DetectPlanarTrunks(Cast(truth, 0.003, 1), PlanarTrunkOptions{});
  ASSERT_EQ(result.trunks.size(), truth.size());
  for (const Trunk& t : truth) {
    bool found = false;
    for (const PlanarTrunk& d : result.trunks) {
      if ((d.tree.position.head<2>() - Eigen::Vector2d(t.x, t.y)).norm() < 0.03) {
        found = true;
        EXPECT_NEAR(d.tree.dbh, 2 * t.radius, 0.02);
        EXPECT_EQ(d.tree.position.z(), 0.0);
        EXPECT_EQ(d.tree.axis, Eigen::Vector3d::UnitZ());
        EXPECT_GE(d.points, 8);
      }
    }
    EXPECT_TRUE(found) << "trunk at " << t.x << ", " << t.y;
  }
  EXPECT_GT(result.rejected_width, 0u);  // the walls
}

TEST(PlanarTrunksTest, RangeAndFieldOfViewFilter) {
  const std::vector<Trunk> truth{{3, 0, 0.15}, {0, 3, 0.15}, {8, 0, 0.15}};
  PlanarTrunkOptions options;
  options.max_range = 5;  // drops the trunk at 8 m
  options.fov_center = 0;
  options.fov_width = 100 * M_PI / 180;  // drops the trunk at 90 degrees
  const PlanarTrunkResult result = DetectPlanarTrunks(Cast(truth, 0.002, 2), options);
  ASSERT_EQ(result.trunks.size(), 1u);
  EXPECT_NEAR(result.trunks[0].tree.position.x(), 3, 0.03);
}

TEST(PlanarTrunksTest, TooFewPointsAndBadInput) {
  PlanarTrunkOptions options;
  options.min_points = 500;
  EXPECT_TRUE(DetectPlanarTrunks(Cast({{3, 0, 0.15}}, 0.002, 3), options).trunks.empty());
  PlanarScan bad;
  bad.angles = {0.f, 0.1f};
  bad.ranges = {1.f};
  EXPECT_THROW(DetectPlanarTrunks(bad, PlanarTrunkOptions{}), std::invalid_argument);
  PlanarScan empty;
  EXPECT_TRUE(DetectPlanarTrunks(empty, PlanarTrunkOptions{}).trunks.empty());
}

}  // namespace
}  // namespace forestmap::algorithms
