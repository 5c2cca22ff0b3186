// Small geometric building blocks against known transforms and brute force.
#include <gtest/gtest.h>

#include <random>

#include "algorithms/core/leveling.h"
#include "algorithms/core/rigid2d.h"
#include "algorithms/relocalization/tilt_refinement.h"
#include "algorithms/relocalization/triangles.h"

namespace forestmap::algorithms {
namespace {

constexpr double kTight = 1e-9;

TEST(Rigid2, RecoversKnownTransformFromNoiselessPairs) {
  Rigid2 truth{0.7, Eigen::Vector2d(3.0, -2.0)};
  Rigid2Accumulator acc;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-20, 20);
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector2d p(u(rng), u(rng));
    acc.Add(p, truth(p));
  }
  const Rigid2 fit = acc.Solve();
  EXPECT_NEAR(fit.yaw, truth.yaw, kTight);
  EXPECT_NEAR((fit.translation - truth.translation).norm(), 0, kTight);
}

TEST(Triangles, KeyIsInvariantToRotationAndVertexOrder) {
  std::vector<Eigen::Vector2d> pts = {{0, 0}, {3, 0}, {1, 2}};
  const Triangle a = MakeTriangle(pts, 0, 1, 2);
  Rigid2 motion{1.1, Eigen::Vector2d(5, 7)};
  std::vector<Eigen::Vector2d> moved = {motion(pts[2]), motion(pts[0]), motion(pts[1])};
  const Triangle b = MakeTriangle(moved, 0, 1, 2);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a.sides[i], b.sides[i], 1e-5);
  EXPECT_LE(a.sides[0], a.sides[1]);
  EXPECT_LE(a.sides[1], a.sides[2]);
  // The canonical vertex order picks the same physical vertices.
  for (int v = 0; v < 3; ++v) {
    EXPECT_NEAR((motion(pts[a.vertex[v]]) - moved[b.vertex[v]]).norm(), 0, 1e-9);
  }
}

TEST(Triangles, EnumerationMatchesBruteForce) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0, 15);
  std::vector<Eigen::Vector2d> pts(120);
  for (auto& p : pts) p = {u(rng), u(rng)};
  TriangleOptions options;
  options.max_side = 3.0;
  options.min_side = 0.5;
  std::vector<std::vector<uint32_t>> neighbours(pts.size());
  for (uint32_t i = 0; i < pts.size(); ++i) {
    for (uint32_t j = 0; j < pts.size(); ++j) {
      if (i != j && (pts[i] - pts[j]).norm() <= options.max_side) neighbours[i].push_back(j);
    }
  }
  auto ok = [&](size_t i, size_t j) {
    const double d = (pts[i] - pts[j]).norm();
    return d >= options.min_side && d <= options.max_side;
  };
  size_t brute = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    for (size_t j = i + 1; j < pts.size(); ++j) {
      for (size_t k = j + 1; k < pts.size(); ++k) brute += ok(i, j) && ok(j, k) && ok(i, k);
    }
  }
  EXPECT_EQ(EnumerateTriangles(pts, neighbours, options).size(), brute);
  EXPECT_GT(brute, 10u);
}

TEST(Leveling, StemAxesOfATiltedSensorGiveItsUpDirection) {
  // Sensor tilted 40 deg about x; stems vertical in the world, with a few degrees of lean.
  const Eigen::Matrix3d world_from_sensor =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::mt19937 rng(3);
  std::normal_distribution<double> lean(0, 0.03);
  std::uniform_real_distribution<double> u(-15, 15);
  std::vector<DetectedTree> trees(40);
  for (auto& t : trees) {
    const Eigen::Vector3d axis_world = Eigen::Vector3d(lean(rng), lean(rng), 1).normalized();
    t.axis = world_from_sensor.transpose() * (rng() % 2 ? axis_world : -axis_world);
    t.position = world_from_sensor.transpose() * Eigen::Vector3d(u(rng), u(rng), -1.5);
  }
  trees[0].axis = Eigen::Vector3d::UnitX();  // a branch mistaken for a stem
  const LevelingResult level = LevelSensor(trees, std::nullopt);
  EXPECT_EQ(level.source, LevelSource::kStemAxes);
  const Eigen::Vector3d up = level.level_from_sensor.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d true_up = world_from_sensor.transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::acos(std::min(1.0, up.dot(true_up))), 0.02);  // rad, ~1 deg
}

TEST(Leveling, GravityWinsAndNoAxesMeansLevel) {
  std::vector<DetectedTree> trees(5);
  const LevelingResult g = LevelSensor(trees, Eigen::Vector3d(0, 0, -9.81));
  EXPECT_EQ(g.source, LevelSource::kGravity);
  EXPECT_TRUE(g.level_from_sensor.isApprox(Eigen::Matrix3d::Identity()));
  const LevelingResult none = LevelSensor(trees, std::nullopt);
  EXPECT_EQ(none.source, LevelSource::kAssumedLevel);
}

TEST(TiltRefinement, RecoversAResidualTiltFromTreeHeightsDespiteOutliers) {
  // The levelled frame is still tilted 2 deg about x: heights seen = true heights rotated.
  const Eigen::Matrix3d residual =
      Eigen::AngleAxisd(-0.035, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-20, 20);
  std::normal_distribution<double> noise(0, 0.05);
  std::vector<Eigen::Vector3d> levelled;
  std::vector<double> map_z;
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector3d truth(u(rng), u(rng), -1.5 + noise(rng));
    levelled.push_back(residual * truth);
    map_z.push_back(10.0 + truth.z() + (i % 10 == 0 ? 2.0 : 0.0));  // 10% gross outliers
  }
  const std::optional<Eigen::Matrix3d> correction = RefineTilt(levelled, map_z);
  ASSERT_TRUE(correction.has_value());
  const Eigen::AngleAxisd left(*correction * residual);
  EXPECT_LT(left.angle(), 0.004);  // rad: the 0.035 rad tilt is removed to within 0.25 deg
  // Too few trees, or no tilt to speak of: no correction.
  EXPECT_FALSE(
      RefineTilt({levelled.begin(), levelled.begin() + 5}, {map_z.begin(), map_z.begin() + 5}));
}

}  // namespace
}  // namespace forestmap::algorithms
