#include "algorithms/simulation/scan_simulation.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "algorithms/core/check.h"
#include "algorithms/core/parallel.h"
#include "algorithms/core/random.h"

namespace forestmap::algorithms {
namespace {

constexpr double kNoHit = std::numeric_limits<double>::infinity();  // a ray's range
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Uniform in (0, 1) from (key, salt); salts here are distinct from the scene's (2i, 2i+1 < 2^62).
double Uniform01(uint64_t key, uint64_t salt) {
  return (static_cast<double>(SplitMix64(key ^ SplitMix64(salt | (1ull << 62))) >> 11) + 0.5) *
         0x1.0p-53;
}

double HashGaussian(uint64_t key, uint64_t salt) {  // Box-Muller
  return std::sqrt(-2 * std::log(Uniform01(key, salt))) *
         std::cos(2 * M_PI * Uniform01(key, salt + 1));
}

// The drone's body in the sensor frame: four arms above the sensor and four landing legs below
// it, all within 0.5 m, as segments (a, b) with a radius (m).
struct BodyPart {
  Eigen::Vector3d a, b;
  double radius;
};

std::vector<BodyPart> DroneBody() {
  std::vector<BodyPart> parts;
  for (int k = 0; k < 4; ++k) {
    const double az = M_PI / 4 + k * M_PI / 2;
    const Eigen::Vector3d dir(std::cos(az), std::sin(az), 0);
    parts.push_back({0.12 * dir + Eigen::Vector3d(0, 0, 0.12),
                     0.45 * dir + Eigen::Vector3d(0, 0, 0.12), 0.015});
    parts.push_back({0.33 * dir + Eigen::Vector3d(0, 0, -0.08),
                     0.33 * dir + Eigen::Vector3d(0, 0, -0.32), 0.01});
  }
  return parts;
}

// Range (m) at which a ray from the sensor origin along unit `d` enters a segment's cylinder.
double BodyHit(const std::vector<BodyPart>& body, const Eigen::Vector3d& d) {
  double best = kNoHit;
  for (const BodyPart& part : body) {
    const Eigen::Vector3d axis = (part.b - part.a).normalized();
    const double length = (part.b - part.a).norm();
    const double b = d.dot(axis);
    const double sin2 = 1 - b * b;
    if (sin2 < 1e-6) continue;
    const Eigen::Vector3d w0 = -part.a;  // ray origin (0) minus segment start
    const double t_c = (b * w0.dot(axis) - w0.dot(d)) / sin2;
    const double s_c = w0.dot(axis) + b * t_c;
    if (t_c <= 0 || s_c < 0 || s_c > length) continue;
    const double miss = (w0 + t_c * d - s_c * axis).norm();
    if (miss >= part.radius) continue;
    best =
        std::min(best, t_c - std::sqrt(part.radius * part.radius - miss * miss) / std::sqrt(sin2));
  }
  return best;
}

float Reflectivity(int32_t label) {  // rough intensity per surface (sensor units, 0-255)
  if (label >= 0) return 60;
  switch (label) {
    case kLabelGround:
      return 30;
    case kLabelShrub:
      return 25;
    case kLabelCrown:
      return 20;
    case kLabelBranch:
      return 50;
    case kLabelBody:
      return 90;
    default:
      return 35;
  }
}

struct ScanContext {
  const ForestScene& scene;
  const Pose3& map_from_sensor;
  const ScannerModel& scanner;
  const ScanNoiseOptions& noise;
  uint32_t seed;
  std::vector<BodyPart> body;
};

// Simulates rings [ring_begin, ring_end) into `result` (already sized).
void SimulateRings(const ScanContext& ctx, int ring_begin, int ring_end,
                   ScanSimulationResult* result) {
  const ScannerModel& scanner = ctx.scanner;
  Ray ray;
  ray.origin = ctx.map_from_sensor.translation();
  ray.footprint_per_m = ctx.noise.beam_divergence ? 0.5 * scanner.beam_divergence : 0.0;
  for (int ring = ring_begin; ring < ring_end; ++ring) {
    const double el = scanner.beam_elevations[ring];
    for (int column = 0; column < scanner.columns; ++column) {
      const size_t index = static_cast<size_t>(ring) * scanner.columns + column;
      const double az = scanner.Azimuth(column);
      const Eigen::Vector3d d_sensor(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                     std::sin(el));
      ray.direction = ctx.map_from_sensor.linear() * d_sensor;
      ray.key = SplitMix64((static_cast<uint64_t>(ctx.seed) << 32) | index);
      const double body = ctx.noise.drone_body ? BodyHit(ctx.body, d_sensor) : kNoHit;
      ray.max_range = std::min(scanner.max_range, body);
      const RayHit hit = ctx.scene.CastRay(ray);
      double range = hit.range;
      int32_t label = hit.label;
      if (body <= scanner.max_range && !(hit.range < body)) {
        range = body;
        label = kLabelBody;
      }
      if (ctx.noise.mixed_pixels && hit.edge_range < range) {
        const double f = hit.edge_fraction;
        range = std::isfinite(range) ? f * hit.edge_range + (1 - f) * range : hit.edge_range;
        label = kLabelMixed;
      }
      if (std::isfinite(range) && ctx.noise.dropout > 0 &&
          Uniform01(ray.key, 1) < ctx.noise.dropout) {
        range = kNoHit;
      }
      if (std::isfinite(range) && ctx.noise.range_noise) {
        range += scanner.range_noise_sd * HashGaussian(ray.key, 2);
      }
      if (!std::isfinite(range) || range < scanner.min_range || range > scanner.max_range) {
        result->cloud.points[index] = Eigen::Vector3f::Constant(kNaN);
        result->labels[index] = kLabelNoReturn;
        result->cloud.intensity[index] = 0;
        continue;
      }
      result->cloud.points[index] = (range * d_sensor).cast<float>();
      result->labels[index] = label;
      result->cloud.intensity[index] = static_cast<float>(
          std::max(0.0, Reflectivity(label) * (1 + 0.1 * HashGaussian(ray.key, 4))));
    }
  }
}

// An organised cloud of the scanner's rings x columns (points, intensities, rings, labels).
void AllocateCloud(const ScannerModel& scanner, ScanSimulationResult& result) {
  const size_t n = static_cast<size_t>(scanner.rings()) * scanner.columns;
  result.cloud.width = static_cast<uint32_t>(scanner.columns);
  result.cloud.height = static_cast<uint32_t>(scanner.rings());
  result.cloud.points.resize(n);
  result.cloud.intensity.resize(n);
  result.cloud.ring.resize(n);
  result.labels.resize(n);
  for (size_t i = 0; i < n; ++i) result.cloud.ring[i] = static_cast<uint16_t>(i / scanner.columns);
}

// The truth per scene tree in the sensor frame: base, DBH, axis and horizontal range.
std::vector<SimulatedTreeTruth> TreeTruth(const ForestScene& scene, const Pose3& map_from_sensor) {
  const Pose3 sensor_from_map = map_from_sensor.inverse();
  const std::vector<SceneTree>& trees = scene.trees();
  std::vector<SimulatedTreeTruth> truths(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) {
    SimulatedTreeTruth& truth = truths[i];
    truth.index = static_cast<int>(i);
    truth.id = trees[i].id;
    truth.position = sensor_from_map * trees[i].base;
    truth.dbh = trees[i].dbh;
    truth.axis = sensor_from_map.linear() * trees[i].axis;
    truth.range =
        (trees[i].PointAt(kBreastHeight).head<2>() - map_from_sensor.translation().head<2>())
            .norm();
  }
  return truths;
}

// Counts the returns, each tree's stem points and those of its visible stem band, and marks the
// trees visible (kMinVisibleStemPoints in the band, within max_range).
void CountReturns(const ForestScene& scene, const Pose3& map_from_sensor,
                  const ScannerModel& scanner, ScanSimulationResult& result) {
  const std::vector<SceneTree>& trees = scene.trees();
  for (size_t i = 0; i < result.labels.size(); ++i) {
    if (result.labels[i] == kLabelNoReturn) continue;
    ++result.returns;
    const int32_t label = result.labels[i];
    if (label < 0) continue;
    const SceneTree& tree = trees[label];
    const double s =
        (map_from_sensor * result.cloud.points[i].cast<double>() - tree.base).dot(tree.axis);
    ++result.trees[label].stem_points;
    if (s >= kVisibleStemLow && s <= kVisibleStemHigh) ++result.trees[label].breast_points;
  }
  for (SimulatedTreeTruth& truth : result.trees) {
    truth.visible =
        truth.breast_points >= kMinVisibleStemPoints && truth.range <= scanner.max_range;
  }
}

}  // namespace

void ScanNoiseOptions::Check() const {
  Require(std::isfinite(dropout) && dropout >= 0 && dropout < 1,
          "ScanNoiseOptions.dropout must be in [0, 1)", dropout);
  Require(threads >= 1 && threads <= 256, "ScanNoiseOptions.threads must be in [1, 256]", threads);
}

ScanSimulationResult SimulateScan(const ForestScene& scene, const Pose3& map_from_sensor,
                                  const ScannerModel& scanner, const ScanNoiseOptions& noise,
                                  uint32_t seed) {
  scanner.Check();
  noise.Check();
  Require(map_from_sensor.matrix().allFinite(), "SimulateScan: map_from_sensor must be finite", 0);
  ScanSimulationResult result;
  result.map_from_sensor = map_from_sensor;
  AllocateCloud(scanner, result);
  // The rings split into contiguous ranges, one thread each: every ray's noise is keyed by the
  // ray, so the cloud does not depend on the split.
  const ScanContext ctx{scene, map_from_sensor, scanner, noise, seed, DroneBody()};
  const int threads = std::min(noise.threads, scanner.rings());
  ParallelFor(static_cast<size_t>(scanner.rings()), threads,
              [&ctx, &result](int, size_t begin, size_t end) {
                SimulateRings(ctx, static_cast<int>(begin), static_cast<int>(end), &result);
              });
  result.trees = TreeTruth(scene, map_from_sensor);
  CountReturns(scene, map_from_sensor, scanner, result);
  return result;
}

PlanarScanSimulationResult SimulatePlanarScan(const ForestScene& scene,
                                              const Pose3& map_from_sensor,
                                              const ScannerModel& scanner,
                                              const ScanNoiseOptions& noise, uint32_t seed) {
  Require(scanner.IsPlanar(), "SimulatePlanarScan: the scanner must have exactly one beam, rings",
          scanner.rings());
  const ScanSimulationResult scan = SimulateScan(scene, map_from_sensor, scanner, noise, seed);
  PlanarScanSimulationResult result;
  result.map_from_sensor = map_from_sensor;
  result.labels = scan.labels;
  std::vector<int> points(scene.trees().size(), 0);
  for (int column = 0; column < scanner.columns; ++column) {
    result.scan.angles.push_back(static_cast<float>(scanner.Azimuth(column)));
    const Eigen::Vector3f& p = scan.cloud.points[column];
    result.scan.ranges.push_back(p.allFinite() ? p.norm() : kNaN);
    if (scan.labels[column] >= 0) ++points[scan.labels[column]];
  }
  const Pose3 sensor_from_map = map_from_sensor.inverse();
  for (size_t i = 0; i < scene.trees().size(); ++i) {
    const SceneTree& tree = scene.trees()[i];
    const Eigen::Vector3d base = sensor_from_map * tree.base;
    const Eigen::Vector3d axis = sensor_from_map.linear() * tree.axis;
    if (std::abs(axis.z()) < 0.1) continue;  // stem (nearly) in the scan plane: no circle
    const double s = -base.z() / axis.z();
    if (s < 0 || s > tree.height) continue;
    PlanarTreeTruth truth;
    truth.index = static_cast<int>(i);
    truth.id = tree.id;
    truth.center = (base + s * axis).head<2>();
    truth.diameter = 2 * tree.RadiusAt(s);
    truth.height = s;
    truth.range = truth.center.norm();
    truth.points = points[i];
    truth.visible = truth.points >= kMinVisiblePlanarPoints && truth.range <= scanner.max_range;
    result.trees.push_back(truth);
  }
  return result;
}

Pose3 DronePose(const ForestScene& scene, double x, double y, double height_above_ground,
                double yaw, double pitch, double roll) {
  Pose3 pose = Pose3::Identity();
  pose.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = Eigen::Vector3d(x, y, scene.TerrainHeight(x, y) + height_above_ground);
  return pose;
}

}  // namespace forestmap::algorithms
