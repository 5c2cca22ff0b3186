// Circle fits against exact circles: Kasa, geometric refinement, RANSAC against clutter.
#include "algorithms/detection/circle_fit.h"

#include <gtest/gtest.h>

#include <random>

namespace forestmap::algorithms {
namespace {

std::vector<Eigen::Vector2d> Arc(const Circle& c, double from, double to, int n, double noise,
                                 std::mt19937& rng) {
  std::normal_distribution<double> gauss(0.0, noise);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < n; ++i) {
    const double a = from + (to - from) * i / (n - 1);
    const double r = c.radius + (noise > 0 ? gauss(rng) : 0.0);
    points.push_back(c.center + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
  return points;
}

TEST(CircleFitTest, KasaIsExactOnAFullCircleFarFromTheOrigin) {
  std::mt19937 rng(1);
  const Circle truth{{5000.3, -2000.7}, 0.21};
  const auto points = Arc(truth, -M_PI, M_PI, 50, 0.0, rng);
  const KasaResult fit = FitCircleKasa(points);
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.circle.center.x(), truth.center.x(), 1e-6);
  EXPECT_NEAR(fit.circle.center.y(), truth.center.y(), 1e-6);
  EXPECT_NEAR(fit.circle.radius, truth.radius, 1e-6);
}

TEST(CircleFitTest, DegenerateInputsFailCleanly) {
  const std::vector<Eigen::Vector2d> two{{0, 0}, {1, 0}};
  EXPECT_FALSE(FitCircleKasa(two).ok);
  const std::vector<Eigen::Vector2d> line{{0, 0}, {1, 0}, {2, 0}, {3, 0}};
  EXPECT_FALSE(FitCircleKasa(line).ok);
  EXPECT_FALSE(CircleFromThreePoints({0, 0}, {1, 1}, {2, 2}).ok);
  std::mt19937 rng(1);
  EXPECT_FALSE(FitCircleRobust(two, CircleRansacOptions{}, rng).success);
}

TEST(CircleFitTest, ThreePointCircle) {
  const KasaResult fit = CircleFromThreePoints({1, 0}, {0, 1}, {-1, 0});
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.circle.center.norm(), 0.0, 1e-12);
  EXPECT_NEAR(fit.circle.radius, 1.0, 1e-12);
}

// On a noisy 90-degree arc (a far stem seen from one side) Kasa shrinks the circle; the
// geometric refinement removes most of that bias.
TEST(CircleFitTest, GeometricRefinementReducesKasaBiasOnShortArcs) {
  const Circle truth{{10.0, 0.0}, 0.15};
  double kasa_error = 0, geometric_error = 0;
  for (uint32_t seed = 0; seed < 50; ++seed) {
    std::mt19937 rng(seed);
    const auto points = Arc(truth, 0.75 * M_PI, 1.25 * M_PI, 30, 0.005, rng);
    const KasaResult kasa = FitCircleKasa(points);
    ASSERT_TRUE(kasa.ok);
    const GeometricFitResult refined = RefineCircleGeometric(points, kasa.circle);
    kasa_error += kasa.circle.radius - truth.radius;
    geometric_error += refined.circle.radius - truth.radius;
    EXPECT_LT(refined.rms, 0.008);
  }
  EXPECT_LT(kasa_error / 50, -0.003);
  EXPECT_LT(std::abs(geometric_error / 50), std::abs(kasa_error / 50) / 2);
}

TEST(CircleFitTest, RansacIgnoresBranchesAndClutter) {
  std::mt19937 rng(3);
  const Circle truth{{3.0, 4.0}, 0.2};
  auto points = Arc(truth, 0.6 * M_PI, 1.6 * M_PI, 60, 0.003, rng);
  std::uniform_real_distribution<double> clutter(-0.5, 0.5);
  for (int i = 0; i < 40; ++i) points.emplace_back(3.0 + clutter(rng), 4.0 + clutter(rng));
  const CircleFitResult fit = FitCircleRobust(points, CircleRansacOptions{}, rng);
  ASSERT_TRUE(fit.success);
  EXPECT_TRUE(fit.used_ransac);
  EXPECT_NEAR(fit.circle.radius, truth.radius, 0.005);
  EXPECT_NEAR((fit.circle.center - truth.center).norm(), 0.0, 0.005);
  EXPECT_GE(fit.inliers, 58);
  EXPECT_NEAR(fit.arc_coverage, 0.5, 0.06);
  EXPECT_EQ(fit.inlier_mask.size(), points.size());
}

TEST(CircleFitTest, CleanPointsSkipRansac) {
  std::mt19937 rng(4);
  const auto points = Arc({{1.0, 1.0}, 0.3}, 0, 2 * M_PI, 80, 0.002, rng);
  const CircleFitResult fit = FitCircleRobust(points, CircleRansacOptions{}, rng);
  ASSERT_TRUE(fit.success);
  EXPECT_FALSE(fit.used_ransac);
  EXPECT_NEAR(fit.circle.radius, 0.3, 0.002);
  EXPECT_GT(fit.arc_coverage, 0.95);
}

TEST(CircleFitTest, ArcCoverageCountsOccupiedSectors) {
  std::mt19937 rng(5);
  const auto quarter = Arc({{0, 0}, 1.0}, 0.01, M_PI / 2 - 0.01, 100, 0.0, rng);
  EXPECT_NEAR(ArcCoverage(quarter, {0, 0}, 36), 0.25, 0.03);
  EXPECT_EQ(ArcCoverage({}, {0, 0}), 0.0);
}

TEST(CircleFitTest, OptionsAreChecked) {
  CircleRansacOptions options;
  options.min_radius = 2;
  options.max_radius = 1;
  EXPECT_THROW(options.Check(), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
