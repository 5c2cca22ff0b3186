#include "algorithms/simulation/scan_simulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "algorithms/simulation/forest_generator.h"
#include "client/io/scan_io.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

constexpr double kDegree = M_PI / 180.0;
constexpr double kNoiseTolerance = 4 * 0.015;  // m, 4 sigma of the Ouster presets' range noise
constexpr double kFloatTolerance = 1e-4;       // m, float storage of points

MapTree Tree(int64_t id, double x, double y, double dbh) {
  MapTree tree;
  tree.id = id;
  tree.position = Eigen::Vector3d(x, y, 0);
  tree.dbh = dbh;
  return tree;
}

// Flat ground, upright untapered stems, nothing else.
SceneOptions BareOptions() {
  SceneOptions options;
  options.crowns = options.branches = options.shrubs = false;
  options.max_slope = options.undulation = options.max_lean = options.taper = 0;
  options.margin = 40;
  return options;
}

ScanNoiseOptions NoNoise() {
  ScanNoiseOptions noise;
  noise.range_noise = false;
  noise.beam_divergence = false;
  noise.drone_body = false;
  return noise;
}

// Horizontal distance (m) of a map-frame point from a tree's (vertical) axis.
double AxisDistance(const SceneTree& tree, const Eigen::Vector3d& p) {
  const Eigen::Vector3d w = p - tree.base;
  return (w - w.dot(tree.axis) * tree.axis).norm();
}

Eigen::Vector3d MapPoint(const ScanSimulationResult& scan, size_t i) {
  return scan.map_from_sensor * scan.cloud.points[i].cast<double>();
}

std::vector<MapTree> SmallForest(double size, unsigned seed) {
  StemMapStatistics stats;
  stats.density = 0.08;
  stats.min_spacing = 1.5;
  ForestOptions options;
  options.width = options.height = size;
  options.seed = seed;
  return GenerateForest(stats, options);
}

TEST(ScannerModelTest, PresetBeamAnglesAndLayout) {
  struct Expected {
    std::string name;
    int rings, columns;
    double top_deg;
  };
  for (const Expected& e : std::vector<Expected>{{"os1-64", 64, 2048, 22.5},
                                                 {"os1-128", 128, 2048, 22.5},
                                                 {"os0-128", 128, 2048, 45},
                                                 {"os2-32-1024", 32, 1024, 11.25},
                                                 {"OS1-64-512", 64, 512, 22.5},
                                                 {"vlp16", 16, 1800, 15}}) {
    SCOPED_TRACE(e.name);
    const ScannerModel model = ScannerPreset(e.name);
    EXPECT_NO_THROW(model.Check());
    ASSERT_EQ(model.rings(), e.rings);
    EXPECT_EQ(model.columns, e.columns);
    EXPECT_NEAR(model.beam_elevations.front(), e.top_deg * kDegree, 1e-12);  // ring 0 = highest
    EXPECT_NEAR(model.beam_elevations.back(), -e.top_deg * kDegree, 1e-12);
    const double spacing = 2 * e.top_deg * kDegree / (e.rings - 1);  // uniform
    for (int r = 1; r < model.rings(); ++r) {
      EXPECT_NEAR(model.beam_elevations[r - 1] - model.beam_elevations[r], spacing, 1e-12);
    }
    // Clockwise like the real sensors: column 0 looks back, the middle column along +x.
    EXPECT_NEAR(model.azimuth_step * model.columns, -2 * M_PI, 1e-12);
    EXPECT_NEAR(WrapAngle(model.Azimuth(0) - M_PI), 0, 1e-12);
    EXPECT_NEAR(model.Azimuth(model.columns / 2), 0, 1e-12);
  }
  EXPECT_NEAR(Vlp16Scanner().beam_elevations[0] - Vlp16Scanner().beam_elevations[1], 2 * kDegree,
              1e-12);
  const ScannerModel planar = PlanarScanner();
  EXPECT_TRUE(planar.IsPlanar());
  EXPECT_EQ(planar.columns, 1081);
  EXPECT_NEAR(planar.Azimuth(0), -135 * kDegree, 1e-12);
  EXPECT_NEAR(planar.Azimuth(1080), 135 * kDegree, 1e-9);
  EXPECT_DOUBLE_EQ(planar.max_range, 30);
  EXPECT_THROW(ScannerPreset("os3-64"), std::invalid_argument);
  EXPECT_THROW(ScannerPreset("os1-48"), std::invalid_argument);
  EXPECT_THROW(ScannerPreset("os1-64-999"), std::invalid_argument);
  EXPECT_THROW(OusterScanner(OusterFamily::kOS1, 64, 100), std::invalid_argument);
}

TEST(ScanSimulationTest, OrganisedLayoutRingsAndNaNs) {
  const ForestScene scene({Tree(1, 6, 0, 0.3)}, BareOptions());
  const ScannerModel scanner = ScannerPreset("os1-64");
  const Pose3 pose = DronePose(scene, 0, 0, 3.0, 0.4);
  const ScanSimulationResult scan = SimulateScan(scene, pose, scanner, ScanNoiseOptions{}, 5);
  ASSERT_EQ(scan.cloud.width, 2048u);
  ASSERT_EQ(scan.cloud.height, 64u);
  ASSERT_EQ(scan.cloud.size(), 2048u * 64u);
  ASSERT_EQ(scan.labels.size(), scan.cloud.size());
  ASSERT_EQ(scan.cloud.ring.size(), scan.cloud.size());
  EXPECT_TRUE(scan.cloud.origin.isZero());
  int nan = 0, upward_returns = 0;
  for (size_t i = 0; i < scan.cloud.size(); ++i) {
    const int ring = static_cast<int>(i / scan.cloud.width);
    const int column = static_cast<int>(i % scan.cloud.width);
    ASSERT_EQ(scan.cloud.ring[i], ring);
    const Eigen::Vector3f& p = scan.cloud.points[i];
    if (scan.labels[i] == kLabelNoReturn) {
      ASSERT_TRUE(std::isnan(p.x()) && std::isnan(p.y()) && std::isnan(p.z()));
      ++nan;
      continue;
    }
    ASSERT_TRUE(p.allFinite());
    // Every return lies along its beam: elevation of its ring, azimuth of its column.
    const double elevation = std::atan2(p.z(), std::hypot(p.x(), p.y()));
    EXPECT_NEAR(elevation, scanner.beam_elevations[ring], 1e-5);
    EXPECT_NEAR(WrapAngle(std::atan2(p.y(), p.x()) - scanner.Azimuth(column)), 0, 1e-5);
    if (scanner.beam_elevations[ring] > 0 && scan.labels[i] != kLabelBody) ++upward_returns;
  }
  EXPECT_EQ(nan + scan.returns, static_cast<int>(scan.cloud.size()));
  // Only the stem (and the drone's arms) are above the sensor: most upward beams see nothing.
  EXPECT_GT(nan, 2048 * 30);
  EXPECT_GT(upward_returns, 0);
  EXPECT_LT(upward_returns, 2048 * 2);
}

TEST(ScanSimulationTest, CylinderReturnsLieOnItsSurface) {
  const double dbh = 0.4;
  const ForestScene scene({Tree(7, 5, 1, dbh)}, BareOptions());
  const SceneTree& tree = scene.trees()[0];
  EXPECT_FALSE(tree.dbh_drawn);
  EXPECT_DOUBLE_EQ(tree.dbh, dbh);
  const Pose3 pose = DronePose(scene, 0, 0, 2.0, 0.2);
  const ScannerModel scanner = ScannerPreset("os1-64");
  // Thin rays, no noise: exactly on the surface.
  ScanSimulationResult exact = SimulateScan(scene, pose, scanner, NoNoise(), 1);
  int stem = 0;
  for (size_t i = 0; i < exact.cloud.size(); ++i) {
    if (exact.labels[i] != 0) continue;
    ++stem;
    EXPECT_NEAR(AxisDistance(tree, MapPoint(exact, i)), dbh / 2, kFloatTolerance);
    EXPECT_LT(MapPoint(exact, i).x(), 5.0);  // on the side facing the sensor
  }
  EXPECT_GT(stem, 300);
  EXPECT_EQ(exact.trees[0].stem_points, stem);
  // Noise and footprint: within the noise, and never more than one footprint outside.
  const ScanSimulationResult noisy = SimulateScan(scene, pose, scanner, ScanNoiseOptions{}, 1);
  const double footprint = 0.5 * scanner.beam_divergence * 5.2;  // m at the stem's range
  for (size_t i = 0; i < noisy.cloud.size(); ++i) {
    if (noisy.labels[i] != 0) continue;
    const double d = AxisDistance(tree, MapPoint(noisy, i));
    EXPECT_GT(d, dbh / 2 - kNoiseTolerance);
    EXPECT_LT(d, dbh / 2 + footprint + kNoiseTolerance);
  }
  // Truth: ground point under the stem, in the sensor frame.
  const SimulatedTreeTruth& truth = noisy.trees[0];
  EXPECT_EQ(truth.id, 7);
  EXPECT_TRUE(((pose * truth.position) - Eigen::Vector3d(5, 1, 0)).norm() < 1e-9);
  EXPECT_TRUE(((pose.linear() * truth.axis) - Eigen::Vector3d::UnitZ()).norm() < 1e-9);
  EXPECT_NEAR(truth.range, std::hypot(5, 1), 1e-9);
  EXPECT_TRUE(truth.visible);
}

TEST(ScanSimulationTest, BeamFootprintWidensStemsAtTheEdges) {
  // At 30 m an OS1 footprint has a radius of 4.7 cm: edge returns land outside the surface.
  const double dbh = 0.3;
  const ForestScene scene({Tree(1, 30, 0, dbh)}, BareOptions());
  const SceneTree& tree = scene.trees()[0];
  const ScannerModel scanner = ScannerPreset("os1-128");
  ScanNoiseOptions noise = NoNoise();
  noise.beam_divergence = true;
  const ScanSimulationResult scan =
      SimulateScan(scene, DronePose(scene, 0, 0, 2.0, 0), scanner, noise, 3);
  const double footprint = 0.5 * scanner.beam_divergence * 30;
  int outside = 0, stem = 0;
  double widest = 0;
  for (size_t i = 0; i < scan.cloud.size(); ++i) {
    if (scan.labels[i] != 0) continue;
    ++stem;
    const double d = AxisDistance(tree, MapPoint(scan, i));
    EXPECT_GT(d, dbh / 2 - kFloatTolerance);
    EXPECT_LT(d, dbh / 2 + footprint + kFloatTolerance);
    if (d > dbh / 2 + 0.005) ++outside;
    widest = std::max(widest, d);
  }
  EXPECT_GT(stem, 100);
  EXPECT_GT(outside, 10);  // the diameter bias real scanners show
  EXPECT_GT(widest, dbh / 2 + 0.3 * footprint);

  // Mixed pixels: beams grazing the stem without returning report a range between the stem's
  // edge and the background, never nearer than the stem.
  noise.mixed_pixels = true;
  const ScanSimulationResult mixed =
      SimulateScan(scene, DronePose(scene, 0, 0, 2.0, 0), scanner, noise, 3);
  int mixed_points = 0;
  for (size_t i = 0; i < mixed.cloud.size(); ++i) {
    if (mixed.labels[i] != kLabelMixed) continue;
    ++mixed_points;
    const Eigen::Vector3d p = MapPoint(mixed, i);
    EXPECT_GT(p.head<2>().norm(), 30 - dbh / 2 - footprint);
    EXPECT_GT(AxisDistance(tree, p), dbh / 2);
  }
  EXPECT_GT(mixed_points, 10);
  EXPECT_EQ(mixed.labels.size(), scan.labels.size());
}

TEST(ScanSimulationTest, GridCastMatchesBruteForce) {
  for (double cell : {1.0, 2.0}) {
    SceneOptions options;
    options.cell_size = cell;
    options.margin = 10;
    options.max_slope = 0.2;
    options.undulation = 1.0;
    options.shrub_density = 0.05;
    options.seed = 11;
    const ForestScene scene(SmallForest(25, 4), options);
    ASSERT_GT(scene.trees().size(), 20u);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> uniform(0, 1);
    int hits = 0, labels_seen = 0;
    std::vector<bool> seen(8, false);
    for (int i = 0; i < 4000; ++i) {
      Ray ray;
      ray.origin = Eigen::Vector3d(uniform(rng) * 25, uniform(rng) * 25, 0);
      ray.origin.z() = scene.TerrainHeight(ray.origin.x(), ray.origin.y()) + 2 + 13 * uniform(rng);
      const double az = 2 * M_PI * uniform(rng), el = std::asin(2 * uniform(rng) - 1);
      ray.direction =
          Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      ray.max_range = 60;
      ray.footprint_per_m = 1.55e-3;
      ray.key = static_cast<uint64_t>(i);
      const RayHit grid = scene.CastRay(ray);
      const RayHit brute = scene.CastRayBruteForce(ray);
      ASSERT_EQ(grid.hit(), brute.hit()) << "ray " << i;
      ASSERT_EQ(grid.label, brute.label) << "ray " << i;
      if (!grid.hit()) continue;
      ++hits;
      ASSERT_NEAR(grid.range, brute.range, 1e-9) << "ray " << i;
      ASSERT_EQ(grid.primitive, brute.primitive);
      const int slot = grid.label >= 0 ? 0 : -grid.label;
      if (!seen[slot]) ++labels_seen;
      seen[slot] = true;
    }
    EXPECT_GT(hits, 2000);
    EXPECT_GE(labels_seen, 5);  // stems, ground, shrubs, crowns, branches all exercised
  }
}

TEST(ScanSimulationTest, VisibleFlagRespondsToOcclusion) {
  const std::vector<MapTree> trees = {Tree(1, 4, 0, 0.6), Tree(2, 10, 0, 0.2), Tree(3, 0, 8, 0.25),
                                      Tree(4, 150, 0, 0.5)};
  const ForestScene scene(trees, BareOptions());
  const ScannerModel scanner = ScannerPreset("os1-64");
  const ScanSimulationResult scan =
      SimulateScan(scene, DronePose(scene, 0, 0, 2.0, 0), scanner, ScanNoiseOptions{}, 2);
  EXPECT_TRUE(scan.trees[0].visible);
  EXPECT_FALSE(scan.trees[1].visible) << "tree 2 stands in tree 1's shadow";
  EXPECT_EQ(scan.trees[1].stem_points, 0);
  EXPECT_TRUE(scan.trees[2].visible);
  EXPECT_FALSE(scan.trees[3].visible) << "beyond max range";
  EXPECT_GE(scan.trees[0].breast_points, kMinVisibleStemPoints);
  // Without the nearer stem, the one behind it is seen.
  const ForestScene open({Tree(2, 10, 0, 0.2)}, BareOptions());
  const ScanSimulationResult open_scan =
      SimulateScan(open, DronePose(open, 0, 0, 2.0, 0), scanner, ScanNoiseOptions{}, 2);
  EXPECT_TRUE(open_scan.trees[0].visible);
  EXPECT_GT(open_scan.trees[0].stem_points, 50);
}

TEST(ScanSimulationTest, DeterministicForASeedAndThreadCount) {
  const std::vector<MapTree> forest = SmallForest(40, 2);
  SceneOptions options;
  options.seed = 9;
  const ForestScene a(forest, options), b(forest, options);
  ASSERT_EQ(a.primitives().size(), b.primitives().size());
  const ScannerModel scanner = ScannerPreset("os1-64-1024");
  const Pose3 pose = DronePose(a, 20, 20, 6, 0.3, 0.1, -0.05);
  ScanNoiseOptions noise;
  noise.mixed_pixels = true;
  noise.dropout = 0.05;
  const ScanSimulationResult first = SimulateScan(a, pose, scanner, noise, 4);
  noise.threads = 3;
  const ScanSimulationResult threaded = SimulateScan(b, pose, scanner, noise, 4);
  const ScanSimulationResult other_seed = SimulateScan(b, pose, scanner, noise, 5);
  ASSERT_EQ(first.cloud.size(), threaded.cloud.size());
  EXPECT_EQ(first.labels, threaded.labels);
  EXPECT_EQ(0, std::memcmp(first.cloud.points.data(), threaded.cloud.points.data(),
                           first.cloud.size() * sizeof(Eigen::Vector3f)));
  EXPECT_NE(first.labels, other_seed.labels);
  for (size_t i = 0; i < first.trees.size(); ++i) {
    EXPECT_EQ(first.trees[i].stem_points, threaded.trees[i].stem_points);
  }
  // Scenes differ with the scene seed.
  options.seed = 10;
  const ForestScene c(forest, options);
  EXPECT_NE(a.trees()[0].height, c.trees()[0].height);
}

TEST(ScanSimulationTest, DroneBodyReturnsStayNearTheSensor) {
  const ForestScene scene(SmallForest(40, 3), SceneOptions{});
  const ScannerModel scanner = ScannerPreset("os1-64");
  const Pose3 pose = DronePose(scene, 20, 20, 8, 1.0);
  const ScanSimulationResult scan = SimulateScan(scene, pose, scanner, ScanNoiseOptions{}, 1);
  int body = 0;
  for (size_t i = 0; i < scan.cloud.size(); ++i) {
    if (scan.labels[i] != kLabelBody) continue;
    ++body;
    const double range = scan.cloud.points[i].norm();
    EXPECT_GE(range, scanner.min_range);
    EXPECT_LT(range, 0.5 + kNoiseTolerance);
  }
  EXPECT_GT(body, 100);
  ScanNoiseOptions no_body;
  no_body.drone_body = false;
  const ScanSimulationResult clean = SimulateScan(scene, pose, scanner, no_body, 1);
  EXPECT_EQ(std::count(clean.labels.begin(), clean.labels.end(), kLabelBody), 0);
}

// Whether a map point lies within `slack` m of an ellipsoid volume (scaled distance).
bool InsideVolume(const ScenePrimitive& p, const Eigen::Vector3d& x, double slack) {
  return ((x - p.origin).cwiseQuotient(p.size + Eigen::Vector3d::Constant(slack))).norm() <= 1;
}

double SegmentDistance(const ScenePrimitive& p, const Eigen::Vector3d& x) {
  const double s = std::clamp((x - p.origin).dot(p.axis), 0.0, p.length);
  return (x - p.origin - s * p.axis).norm();
}

TEST(ScanSimulationTest, LabelsMatchGeometryOnRoughTerrain) {
  SceneOptions options;
  options.max_slope = 0.25;
  options.undulation = 1.5;
  options.shrub_density = 0.03;
  options.max_branches = 8;
  options.seed = 21;
  const ForestScene scene(SmallForest(40, 6), options);
  const ScannerModel scanner = ScannerPreset("os0-64");
  const Pose3 pose = DronePose(scene, 20, 20, 4, 0.7, 0.15, 0.1);  // tilted drone
  const ScanSimulationResult scan = SimulateScan(scene, pose, scanner, ScanNoiseOptions{}, 8);
  std::vector<int> count(8, 0);
  const double slack = kNoiseTolerance + 0.5 * scanner.beam_divergence * scanner.max_range;
  for (size_t i = 0; i < scan.cloud.size(); ++i) {
    const int32_t label = scan.labels[i];
    if (label == kLabelNoReturn || label == kLabelBody) continue;
    const Eigen::Vector3d p = MapPoint(scan, i);
    ++count[label >= 0 ? 0 : -label];
    if (label == kLabelGround) {
      ASSERT_NEAR(p.z(), scene.TerrainHeight(p.x(), p.y()), kNoiseTolerance) << "point " << i;
    } else if (label >= 0) {
      const SceneTree& tree = scene.trees()[label];
      const double s = (p - tree.base).dot(tree.axis);
      ASSERT_GT(s, -kNoiseTolerance);
      ASSERT_LT(s, tree.height + kNoiseTolerance);
      const double d = AxisDistance(tree, p);
      ASSERT_GT(d, tree.RadiusAt(s) - kNoiseTolerance) << "point " << i;
      ASSERT_LT(d, tree.RadiusAt(s) + slack) << "point " << i;
    } else {
      bool explained = false;
      for (const ScenePrimitive& primitive : scene.primitives()) {
        if (primitive.label != label) continue;
        explained = explained || (primitive.kind == ScenePrimitive::Kind::kVolume
                                      ? InsideVolume(primitive, p, kNoiseTolerance)
                                      : SegmentDistance(primitive, p) < primitive.radius + slack);
      }
      ASSERT_TRUE(explained) << "point " << i << " label " << label;
    }
  }
  EXPECT_GT(count[0], 500);  // stems
  EXPECT_GT(count[-kLabelGround], 10000);
  EXPECT_GT(count[-kLabelShrub], 50);
  EXPECT_GT(count[-kLabelCrown], 1000);
  EXPECT_GT(count[-kLabelBranch], 5);
}

TEST(PlanarScanSimulationTest, TruthCirclesMatchReturns) {
  const std::vector<MapTree> trees = {Tree(1, 5, 0, 0.3),  Tree(2, 12, 0, 0.2),
                                      Tree(3, 0, 6, 0.45), Tree(4, -3, -4, 0.25),
                                      Tree(5, 40, 5, 0.5), Tree(6, -6, 0.5, 0.3)};
  const ForestScene scene(trees, BareOptions());
  const ScannerModel scanner = PlanarScanner();
  const Pose3 pose = DronePose(scene, 0, 0, kBreastHeight, 0.1);
  const PlanarScanSimulationResult result =
      SimulatePlanarScan(scene, pose, scanner, ScanNoiseOptions{}, 3);
  ASSERT_EQ(result.scan.size(), 1081u);
  ASSERT_EQ(result.scan.angles.size(), 1081u);
  ASSERT_EQ(result.trees.size(), trees.size());
  const Pose3 sensor_from_map = pose.inverse();
  for (const PlanarTreeTruth& truth : result.trees) {
    SCOPED_TRACE(truth.id);
    const Eigen::Vector3d expected = sensor_from_map * scene.trees()[truth.index].base;
    EXPECT_NEAR((truth.center - expected.head<2>()).norm(), 0, 1e-9);
    EXPECT_NEAR(truth.height, kBreastHeight, 1e-9);
    EXPECT_NEAR(truth.diameter, trees[truth.index].dbh, 1e-9);
    int on_circle = 0;
    for (size_t i = 0; i < result.scan.size(); ++i) {
      if (result.labels[i] != truth.index) continue;
      const Eigen::Vector2d p =
          result.scan.ranges[i] *
          Eigen::Vector2d(std::cos(result.scan.angles[i]), std::sin(result.scan.angles[i]));
      const double d = (p - truth.center).norm();
      EXPECT_GT(d, truth.diameter / 2 - kNoiseTolerance);
      EXPECT_LT(d, truth.diameter / 2 + 0.05 + kNoiseTolerance);
      ++on_circle;
    }
    EXPECT_EQ(on_circle, truth.points);
  }
  EXPECT_TRUE(result.trees[0].visible);
  EXPECT_FALSE(result.trees[1].visible) << "hidden behind tree 1";
  EXPECT_TRUE(result.trees[2].visible);
  EXPECT_TRUE(result.trees[3].visible);
  EXPECT_FALSE(result.trees[4].visible) << "beyond 30 m";
  EXPECT_FALSE(result.trees[5].visible) << "behind the scanner, outside its 270 deg";
  EXPECT_THROW(SimulatePlanarScan(scene, pose, ScannerPreset("os1-64"), {}, 1),
               std::invalid_argument);
}

TEST(ScanSimulationTest, UnknownDbhIsDrawnAndInvalidInputThrows) {
  MapTree unknown = Tree(3, 0, 0, kUnknown);
  const ForestScene scene({unknown, Tree(4, 3, 0, 0)}, SceneOptions{});
  for (const SceneTree& tree : scene.trees()) {
    EXPECT_TRUE(tree.dbh_drawn);
    EXPECT_GE(tree.dbh, 0.05);
    EXPECT_LE(tree.dbh, 1.2);
    EXPECT_GT(tree.height, tree.crown_base);
  }
  MapTree bad = Tree(9, 0, 0, 0.2);
  bad.position.x() = std::nan("");
  EXPECT_THROW(ForestScene({bad}, SceneOptions{}), std::invalid_argument);
  SceneOptions bad_options;
  bad_options.cell_size = 0;
  EXPECT_THROW(ForestScene({}, bad_options), std::invalid_argument);
  ScanNoiseOptions bad_noise;
  bad_noise.dropout = 1;
  EXPECT_THROW(SimulateScan(scene, Pose3::Identity(), PlanarScanner(), bad_noise, 1),
               std::invalid_argument);
}

// What `forestmap-lab simulate` writes reads back as the same organised scan (client/io/scan_io.h).
TEST(ScanSimulationTest, ScansRoundTripThroughPcd) {
  const ForestScene scene(SmallForest(30, 8), SceneOptions{});
  const ScanSimulationResult scan =
      SimulateScan(scene, DronePose(scene, 15, 15, 5, 0.2), ScannerPreset("os1-32-512"), {}, 6);
  const std::string path =
      (std::filesystem::temp_directory_path() / "scan_simulation_test_roundtrip.pcd").string();
  client::WriteScan(path, scan.cloud);
  const PointCloud read = client::ReadScan(path);
  std::filesystem::remove(path);
  ASSERT_EQ(read.width, scan.cloud.width);
  ASSERT_EQ(read.height, scan.cloud.height);
  ASSERT_EQ(read.size(), scan.cloud.size());
  ASSERT_EQ(read.ring, scan.cloud.ring);
  for (size_t i = 0; i < read.size(); ++i) {
    ASSERT_EQ(read.points[i].allFinite(), scan.cloud.points[i].allFinite()) << i;
    if (read.points[i].allFinite()) {
      ASSERT_EQ(read.points[i], scan.cloud.points[i]) << i;
    }
  }
}

// The real longleaf pine stem map (200 m x 200 m, 584 trees with DBH): trees near a drone flying
// 3 m above the ground are seen, trees beyond the scanner's range never are.
TEST(ScanSimulationRealDataTest, LongleafNearTreesVisibleFarOnesNot) {
  const std::string path = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/spatstat_longleaf.csv";
  if (!std::filesystem::exists(path))
    FORESTMAP_SKIP_WITHOUT_DATA() << "real data missing: " << path;
  const std::vector<MapTree> map = client::ToMapTrees(client::ReadMapTreesCsv(path));
  ASSERT_EQ(map.size(), 584u);
  const ForestScene scene(map, SceneOptions{});
  const ScannerModel scanner = ScannerPreset("os1-64");
  const ScanSimulationResult scan =
      SimulateScan(scene, DronePose(scene, 100, 100, 3, 0.5), scanner, ScanNoiseOptions{}, 1);
  int near = 0, near_visible = 0, mid = 0, mid_visible = 0, far_visible = 0;
  for (const SimulatedTreeTruth& tree : scan.trees) {
    if (tree.range < 15) {
      ++near;
      near_visible += tree.visible;
    } else if (tree.range > 40 && tree.range < scanner.max_range) {
      ++mid;
      mid_visible += tree.visible;
    } else if (tree.range > scanner.max_range) {
      far_visible += tree.visible;
    }
  }
  ASSERT_GT(near, 3);
  EXPECT_GE(near_visible, 0.7 * near) << near_visible << " of " << near;
  EXPECT_EQ(far_visible, 0);
  EXPECT_LT(static_cast<double>(mid_visible) / mid, 0.5 * near_visible / near)
      << "occlusion hides most distant stems: " << mid_visible << " of " << mid;
}

}  // namespace
}  // namespace forestmap::algorithms
