// Cylinder fits against exact, leaning cylinders: a partial view, clutter beside the stem, few
// points, the radius prior that keeps a short flat arc from running away, and the silhouette's
// tangent rays that fix its radius.
#include "algorithms/detection/cylinder_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <iostream>
#include <random>
#include <vector>

namespace forestmap::algorithms {
namespace {

// `n` points on the part of the cylinder within +-half_angle of the direction to the origin
// (what a sensor at the origin sees), heights in [z0, z1], radial noise `noise` (m).
std::vector<Eigen::Vector3d> Surface(const Cylinder& c, double half_angle, double z0, double z1,
                                     int n, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> gauss(0, noise);
  const Eigen::Vector3d& a = c.direction;
  const Eigen::Vector3d toward = Eigen::Vector3d(-c.point.x(), -c.point.y(), 0).normalized();
  const Eigen::Vector3d e1 = (toward - toward.dot(a) * a).normalized(), e2 = a.cross(e1);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double z = z0 + (z1 - z0) * u(rng);
    const double angle = half_angle * (2 * u(rng) - 1);
    const Eigen::Vector3d on_axis = c.point + (z - c.point.z()) / a.z() * a;
    const double r = c.radius + (noise > 0 ? gauss(rng) : 0.0);
    points.push_back(on_axis + r * (std::cos(angle) * e1 + std::sin(angle) * e2));
  }
  return points;
}

double AxisOffsetAt(const Cylinder& a, const Cylinder& b, double z) {
  const Eigen::Vector3d pa = a.point + (z - a.point.z()) / a.direction.z() * a.direction;
  const Eigen::Vector3d pb = b.point + (z - b.point.z()) / b.direction.z() * b.direction;
  return (pa - pb).head<2>().norm();
}

const Cylinder kTruth{{12.0, 5.0, -8.0}, Eigen::Vector3d(0.05, -0.03, 1).normalized(), 0.14};

TEST(CylinderFitTest, ExactOnAHalfViewOfALeaningStem) {
  std::mt19937 rng(1);
  const auto points = Surface(kTruth, M_PI / 2, -9.5, -7.0, 200, 0.0, rng);
  const Cylinder seed{{12.1, 5.1, -8.0}, Eigen::Vector3d::UnitZ(), 0.10};
  const CylinderFitResult fit = FitCylinder(points, seed);
  ASSERT_TRUE(fit.success);
  EXPECT_NEAR(fit.cylinder.radius, kTruth.radius, 1e-5);
  EXPECT_NEAR(fit.cylinder.direction.dot(kTruth.direction), 1.0, 1e-8);
  EXPECT_NEAR(AxisOffsetAt(fit.cylinder, kTruth, -8.0), 0, 1e-5);
  EXPECT_EQ(fit.inliers, 200);
  EXPECT_LT(fit.radius_sd, 1e-4);
}

TEST(CylinderFitTest, NoiseAndABranchBesideTheStemBarelyMoveIt) {
  std::mt19937 rng(2);
  auto points = Surface(kTruth, M_PI / 2, -9.5, -7.0, 150, 0.01, rng);
  // A branch: 30 points on a line leaving the stem sideways at -7.2 m.
  for (int i = 0; i < 30; ++i) {
    points.push_back(Eigen::Vector3d(12.0, 5.0 - kTruth.radius - 0.01 * i, -7.2 + 0.01 * i));
  }
  const Cylinder seed{{12.0, 5.0, -8.0}, Eigen::Vector3d::UnitZ(), 0.12};
  const CylinderFitResult fit = FitCylinder(points, seed);
  ASSERT_TRUE(fit.success);
  EXPECT_NEAR(fit.cylinder.radius, kTruth.radius, 0.006);
  EXPECT_NEAR(AxisOffsetAt(fit.cylinder, kTruth, -8.0), 0, 0.01);
  EXPECT_GT(fit.radius_sd, 0);
  EXPECT_LT(fit.radius_sd, 0.006);
}

TEST(CylinderFitTest, RadiusPriorHoldsShortFlatArcs) {
  // Far stems: 14 points on +-20 deg of the front, 1.5 cm noise, from a seed 2 cm too wide. The
  // arcs alone hardly tell the radius; with the silhouette's prior (the true radius + 5 mm) the
  // fits stay near it.
  std::mt19937 rng(3);
  const Cylinder truth{{0, 18.0, -8.0}, Eigen::Vector3d::UnitZ(), 0.06};
  const Cylinder seed{{0, 18.02, -8.0}, Eigen::Vector3d::UnitZ(), 0.08};
  RadiusPrior prior;
  prior.radius = 0.065;
  prior.sd_below = 0.005;
  prior.sd_above = 0.03;
  double free2 = 0, held2 = 0;
  constexpr int kTrials = 40;
  for (int trial = 0; trial < kTrials; ++trial) {
    const auto points = Surface(truth, 0.35, -9.5, -7.0, 14, 0.015, rng);
    const CylinderFitResult free_fit = FitCylinder(points, seed);
    const CylinderFitResult held = FitCylinder(points, seed, {}, prior);
    ASSERT_TRUE(held.success);
    const double free_error = free_fit.success ? free_fit.cylinder.radius - truth.radius : 1.0;
    free2 += free_error * free_error;
    held2 += std::pow(held.cylinder.radius - truth.radius, 2);
  }
  const double free_rmse = std::sqrt(free2 / kTrials), held_rmse = std::sqrt(held2 / kTrials);
  std::cout << "radius rmse: free " << free_rmse << " m, with prior " << held_rmse << " m\n";
  EXPECT_LT(held_rmse, 0.015);
  EXPECT_LT(held_rmse, 0.5 * free_rmse);
}

// The two rays from the origin grazing a vertical cylinder at elevation `elevation` (rad).
std::vector<TangentRay> GrazingRays(const Cylinder& c, double elevation, double sd) {
  const double distance = c.point.head<2>().norm();
  const double centre = std::atan2(c.point.y(), c.point.x());
  const double half = std::asin(c.radius / distance);
  std::vector<TangentRay> rays;
  for (double azimuth : {centre - half, centre + half}) {
    TangentRay ray;
    ray.direction = Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                    std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    ray.sd = sd;
    rays.push_back(ray);
  }
  return rays;
}

TEST(CylinderFitTest, TangentRaysFixTheRadiusOfShortFlatArcs) {
  // The far stem of RadiusPriorHoldsShortFlatArcs seen by six beam rings, each giving the two
  // silhouette edges within 1 cm; one ring's edge is 8 cm off (a branch beside the stem) and the
  // robust weights ignore it.
  std::mt19937 rng(4);
  std::normal_distribution<double> jitter(0, 0.01 / 18.0);  // rad, 1 cm at 18 m
  const Cylinder truth{{0, 18.0, -8.0}, Eigen::Vector3d::UnitZ(), 0.06};
  const Cylinder seed{{0, 18.02, -8.0}, Eigen::Vector3d::UnitZ(), 0.08};
  double held2 = 0, offset2 = 0;
  constexpr int kTrials = 40;
  for (int trial = 0; trial < kTrials; ++trial) {
    const auto points = Surface(truth, 0.35, -9.5, -7.0, 14, 0.015, rng);
    std::vector<TangentRay> rays;
    for (int ring = 0; ring < 6; ++ring) {
      for (TangentRay ray : GrazingRays(truth, -0.4 - 0.02 * ring, 0.01)) {
        const double turn = jitter(rng) + (ring == 2 && rays.size() % 2 ? 0.08 / 18.0 : 0.0);
        ray.direction = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()) * ray.direction;
        rays.push_back(ray);
      }
    }
    const CylinderFitResult fit = FitCylinder(points, seed, {}, {}, rays);
    ASSERT_TRUE(fit.success);
    held2 += std::pow(fit.cylinder.radius - truth.radius, 2);
    offset2 += std::pow(AxisOffsetAt(fit.cylinder, truth, -8.0), 2);
  }
  const double radius_rmse = std::sqrt(held2 / kTrials);
  const double axis_rmse = std::sqrt(offset2 / kTrials);
  std::cout << "with tangent rays: radius rmse " << radius_rmse << " m, axis rmse " << axis_rmse
            << " m\n";
  EXPECT_LT(radius_rmse, 0.005);
  EXPECT_LT(axis_rmse, 0.015);
}

TEST(CylinderFitTest, TooFewPointsOrBadSeedsFailCleanly) {
  std::mt19937 rng(4);
  const auto points = Surface(kTruth, M_PI / 2, -9.5, -7.0, 5, 0.0, rng);
  EXPECT_FALSE(FitCylinder(points, kTruth).success);
  const auto more = Surface(kTruth, M_PI / 2, -9.5, -7.0, 50, 0.0, rng);
  EXPECT_FALSE(FitCylinder(more, Cylinder{kTruth.point, kTruth.direction, 0.0}).success);
  EXPECT_FALSE(FitCylinder(more, Cylinder{kTruth.point, -Eigen::Vector3d::UnitZ(), 0.1}).success);
  CylinderFitOptions options;
  options.huber_scale = 0;
  EXPECT_THROW(FitCylinder(more, kTruth, options), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
