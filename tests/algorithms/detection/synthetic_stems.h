#pragma once
// A tiny ray caster for detection unit tests: a rotating multi-beam LiDAR at the origin over a
// planar (possibly sloped) ground with vertical, tapered stems and optional clutter. Exact truth,
// no dependency on the full scan simulator.

#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <vector>

#include "algorithms/core/point_cloud.h"

namespace forestmap::algorithms::testing {

struct SyntheticStem {
  double x = 0, y = 0;  // m, stem base (on the ground plane)
  double dbh = 0.3;     // m, at 1.3 m above ground
  double taper = 0.01;  // m of diameter lost per m of height
  double height = 8;    // m above ground
  double porosity = 0;  // [0, 1), share of the beams that pass through (a crown-like volume)
};

struct SyntheticScene {
  std::vector<SyntheticStem> stems;
  double ground_z = -10;  // m, ground height under the sensor (z = ground_z + sx x + sy y)
  double slope_x = 0, slope_y = 0;
  bool ground = true;  // false: no ground plane at all
};

struct SyntheticScanner {
  int rings = 64;
  int columns = 2048;
  double min_elevation = -0.7854;  // rad
  double max_elevation = 0.3927;   // rad
  double max_range = 60;           // m
  double noise_sd = 0.005;         // m, range noise
};

inline double GroundZ(const SyntheticScene& scene, double x, double y) {
  return scene.ground_z + scene.slope_x * x + scene.slope_y * y;
}

// Distance along the unit ray `d` from the origin to the stem surface, if hit.
inline std::optional<double> HitStem(const SyntheticScene& scene, const SyntheticStem& stem,
                                     const Eigen::Vector3d& d) {
  const double base_z = GroundZ(scene, stem.x, stem.y);
  double radius = 0.5 * (stem.dbh + stem.taper * 1.3);
  for (int it = 0; it < 3; ++it) {  // radius depends on the hit height: iterate
    const Eigen::Vector2d dir = d.head<2>();
    const double a = dir.squaredNorm();
    if (a < 1e-12) return std::nullopt;
    const Eigen::Vector2d c(stem.x, stem.y);
    const double b = -2.0 * dir.dot(c);
    const double cc = c.squaredNorm() - radius * radius;
    const double disc = b * b - 4 * a * cc;
    if (disc < 0) return std::nullopt;
    const double t = (-b - std::sqrt(disc)) / (2 * a);
    if (t <= 0) return std::nullopt;
    const double h = t * d.z() - base_z;
    if (h < 0 || h > stem.height) return std::nullopt;
    const double new_radius = 0.5 * (stem.dbh - stem.taper * (h - 1.3));
    if (it == 2 || std::abs(new_radius - radius) < 1e-5) return t;
    radius = new_radius;
  }
  return std::nullopt;
}

inline PointCloud CastScan(const SyntheticScene& scene, const SyntheticScanner& scanner,
                           uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, scanner.noise_sd);
  PointCloud cloud;
  cloud.width = scanner.columns;
  cloud.height = scanner.rings;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.points.assign(static_cast<size_t>(scanner.rings) * scanner.columns,
                      Eigen::Vector3f(nan, nan, nan));
  for (int ring = 0; ring < scanner.rings; ++ring) {
    const double el = scanner.max_elevation - (scanner.max_elevation - scanner.min_elevation) *
                                                  ring / std::max(1, scanner.rings - 1);
    for (int col = 0; col < scanner.columns; ++col) {
      const double az = -M_PI + 2 * M_PI * col / scanner.columns;
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      double best = scanner.max_range;
      if (scene.ground) {
        // z(t) = t d.z = ground_z + sx t d.x + sy t d.y
        const double denom = d.z() - scene.slope_x * d.x() - scene.slope_y * d.y();
        if (std::abs(denom) > 1e-9) {
          const double t = scene.ground_z / denom;
          if (t > 0) best = std::min(best, t);
        }
      }
      for (const SyntheticStem& stem : scene.stems) {
        if (stem.porosity > 0 &&
            std::uniform_real_distribution<double>(0, 1)(rng) < stem.porosity) {
          continue;
        }
        const std::optional<double> t = HitStem(scene, stem, d);
        if (t && *t < best) best = *t;
      }
      if (best >= scanner.max_range) continue;
      const double range = best + noise(rng);
      cloud.points[static_cast<size_t>(ring) * scanner.columns + col] = (range * d).cast<float>();
    }
  }
  return cloud;
}

// Unorganised cloud of ring points on a vertical stem slice (all around), like merged scans.
inline PointCloud StemSlice(double cx, double cy, double radius, double z0, double z1, int n,
                            double noise_sd, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), z(z0, z1);
  std::normal_distribution<double> noise(0.0, noise_sd);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    const double a = angle(rng), r = radius + noise(rng);
    cloud.points.emplace_back(cx + r * std::cos(a), cy + r * std::sin(a), z(rng));
  }
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  return cloud;
}

}  // namespace forestmap::algorithms::testing
