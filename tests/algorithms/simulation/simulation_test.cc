#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

constexpr double kDeg = M_PI / 180.0;

double Horizontal(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return (a.head<2>() - b.head<2>()).norm();
}

StemMapStatistics PoissonStats() {
  StemMapStatistics stats;
  stats.density = 0.05;
  stats.min_spacing = 1.0;
  return stats;
}

std::vector<MapTree> Forest(const StemMapStatistics& stats, double size, unsigned seed,
                            double z_amplitude = 0) {
  ForestOptions options;
  options.width = options.height = size;
  options.seed = seed;
  options.z_amplitude = z_amplitude;
  return GenerateForest(stats, options);
}

// The real longleaf stem map (tree_id,x_m,y_m,dbh_m), or empty when the data is missing.
std::vector<MapTree> LoadLongleaf() {
  const std::string path = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/spatstat_longleaf.csv";
  if (!std::filesystem::exists(path)) return {};
  return client::ToMapTrees(client::ReadMapTreesCsv(path));
}

TEST(GenerateForestTest, RespectsAreaSpacingIdsAndDbh) {
  StemMapStatistics stats = PoissonStats();
  stats.cluster_fraction = 0.4;
  ForestOptions options;
  options.width = 200;
  options.height = 150;
  options.seed = 3;
  const std::vector<MapTree> trees = GenerateForest(stats, options);
  ASSERT_EQ(trees.size(), 1500u);  // density * area; all fit at this hard-core coverage
  for (size_t i = 0; i < trees.size(); ++i) {
    EXPECT_EQ(trees[i].id, static_cast<int64_t>(i));
    EXPECT_GE(trees[i].position.x(), 0);
    EXPECT_LT(trees[i].position.x(), options.width);
    EXPECT_GE(trees[i].position.y(), 0);
    EXPECT_LT(trees[i].position.y(), options.height);
    EXPECT_EQ(trees[i].position.z(), 0);
    EXPECT_GE(trees[i].dbh, 0.02);
    EXPECT_LE(trees[i].dbh, 2.0);
    for (size_t j = 0; j < i; ++j) {
      ASSERT_GE(Horizontal(trees[i].position, trees[j].position), stats.min_spacing);
    }
  }
}

TEST(GenerateForestTest, TerrainIsBoundedAndSmooth) {
  constexpr double kAmplitude = 5;                          // m
  constexpr double kMaxSlope = kAmplitude * 2 * M_PI / 50;  // shortest wavelength 50 m
  const std::vector<MapTree> trees = Forest(PoissonStats(), 100, 4, kAmplitude);
  const TreeGrid grid(trees);
  double z_min = 1e9, z_max = -1e9;
  for (size_t i = 0; i < trees.size(); ++i) {
    ASSERT_LE(std::abs(trees[i].position.z()), kAmplitude);
    z_min = std::min(z_min, trees[i].position.z());
    z_max = std::max(z_max, trees[i].position.z());
    const MapTree& neighbour = trees[grid.Nearest(trees[i].position.head<2>(), i)];
    EXPECT_LE(std::abs(neighbour.position.z() - trees[i].position.z()),
              kMaxSlope * Horizontal(neighbour.position, trees[i].position) + 1e-9);
  }
  EXPECT_GT(z_max - z_min, 1.0);  // not flat
}

TEST(GenerateForestTest, UnknownDbhAndDeterminism) {
  StemMapStatistics stats = PoissonStats();
  stats.has_dbh = false;
  const std::vector<MapTree> a = Forest(stats, 60, 7), b = Forest(stats, 60, 7);
  const std::vector<MapTree> c = Forest(stats, 60, 8);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].position, b[i].position);
    EXPECT_FALSE(IsKnown(a[i].dbh));
  }
  EXPECT_NE(a[0].position, c[0].position);
}

TEST(GenerateForestTest, InvalidInputThrows) {
  StemMapStatistics stats = PoissonStats();
  ForestOptions options;
  options.width = 0;
  EXPECT_THROW(GenerateForest(stats, options), std::invalid_argument);
  options = {};
  options.z_amplitude = -1;
  EXPECT_THROW(GenerateForest(stats, options), std::invalid_argument);
  stats.density = 0;
  EXPECT_THROW(GenerateForest(stats, {}), std::invalid_argument);
  stats = PoissonStats();
  stats.min_spacing = 10;  // discs of 10 m at 0.05 trees/m^2 cannot be packed
  EXPECT_THROW(GenerateForest(stats, {}), std::invalid_argument);
  stats = PoissonStats();
  stats.cluster_fraction = 1.5;
  EXPECT_THROW(GenerateForest(stats, {}), std::invalid_argument);
}

TEST(EstimateStatisticsTest, RecoversGeneratingStatistics) {
  const StemMapStatistics truth = PoissonStats();
  const std::vector<MapTree> trees = Forest(truth, 200, 11);
  const StemMapStatistics estimate = EstimateStemMapStatistics(trees);
  EXPECT_NEAR(estimate.density, truth.density, 0.1 * truth.density);
  EXPECT_GE(estimate.min_spacing, truth.min_spacing);
  EXPECT_LE(estimate.min_spacing, 1.3 * truth.min_spacing);
  EXPECT_LT(estimate.cluster_fraction, 0.1);  // a hard-core Poisson forest is not clustered
  EXPECT_TRUE(estimate.has_dbh);
  EXPECT_NEAR(estimate.dbh_log_mean, truth.dbh_log_mean, 0.05);
  EXPECT_NEAR(estimate.dbh_log_sd, truth.dbh_log_sd, 0.05);
}

TEST(EstimateStatisticsTest, DetectsClustering) {
  StemMapStatistics truth = PoissonStats();
  truth.min_spacing = 0.5;
  truth.cluster_fraction = 0.6;
  truth.cluster_radius = 3;
  // Cluster statistics are noisy (a few hundred clusters): a large plot, loose tolerances.
  const std::vector<MapTree> trees = Forest(truth, 400, 12);
  const StemMapStatistics estimate = EstimateStemMapStatistics(trees);
  EXPECT_NEAR(estimate.density, truth.density, 0.1 * truth.density);
  EXPECT_NEAR(estimate.cluster_fraction, truth.cluster_fraction, 0.2);
  EXPECT_NEAR(estimate.cluster_radius, truth.cluster_radius, 0.5 * truth.cluster_radius);
}

TEST(EstimateStatisticsTest, RealLongleafStemMap) {
  const std::vector<MapTree> trees = LoadLongleaf();
  if (trees.empty())
    FORESTMAP_SKIP_WITHOUT_DATA() << "missing " FORESTMAP_SHARED_DATA
                                     "/stemmaps/spatstat_longleaf.csv";
  ASSERT_EQ(trees.size(), 584u);
  const StemMapStatistics stats = EstimateStemMapStatistics(trees);
  constexpr double kTrueDensity = 584.0 / (200.0 * 200.0);  // trees/m^2
  EXPECT_NEAR(stats.density, kTrueDensity, 0.1 * kTrueDensity);
  EXPECT_GT(stats.min_spacing, 0.0);
  EXPECT_LT(stats.min_spacing, 3.0);
  EXPECT_TRUE(stats.has_dbh);
  EXPECT_GT(std::exp(stats.dbh_log_mean), 0.05);  // longleaf pines: median DBH of decimetres
  EXPECT_LT(std::exp(stats.dbh_log_mean), 0.6);
  EXPECT_GT(stats.cluster_fraction, 0.0);  // the longleaf pattern is known to be clustered
  // The statistics generate a forest of the same density.
  const std::vector<MapTree> generated = Forest(stats, 200, 1);
  EXPECT_NEAR(generated.size(), 584.0, 0.1 * 584.0);
}

TEST(EstimateStatisticsTest, InvalidInputThrows) {
  EXPECT_THROW(EstimateStemMapStatistics(Forest(PoissonStats(), 10, 1)), std::invalid_argument);
  std::vector<MapTree> line(20);
  for (size_t i = 0; i < line.size(); ++i) line[i].position = Eigen::Vector3d(i, 0, 0);
  EXPECT_THROW(EstimateStemMapStatistics(line), std::invalid_argument);
  std::vector<MapTree> trees = Forest(PoissonStats(), 50, 1);
  trees[3].position.x() = kUnknown;
  EXPECT_THROW(EstimateStemMapStatistics(trees), std::invalid_argument);
}

TEST(TreeGridTest, MatchesBruteForce) {
  StemMapStatistics stats = PoissonStats();
  stats.cluster_fraction = 0.5;
  const std::vector<MapTree> trees = Forest(stats, 80, 5);
  const TreeGrid grid(trees);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> coordinate(-30, 110);  // also outside the extent
  for (int q = 0; q < 300; ++q) {
    const Eigen::Vector2d c(coordinate(rng), coordinate(rng));
    const double radius = 0.5 + q % 20;
    std::set<int> expected;
    int nearest = -1;
    for (size_t i = 0; i < trees.size(); ++i) {
      const double d = (trees[i].position.head<2>() - c).norm();
      if (d <= radius) expected.insert(i);
      if (nearest < 0 || d < (trees[nearest].position.head<2>() - c).norm()) nearest = i;
    }
    const std::vector<int> found = grid.InRadius(c, radius);
    EXPECT_EQ(std::set<int>(found.begin(), found.end()), expected);
    EXPECT_EQ(found.size(), expected.size());
    const int got = grid.Nearest(c);
    EXPECT_DOUBLE_EQ((trees[got].position.head<2>() - c).norm(),
                     (trees[nearest].position.head<2>() - c).norm());
  }
}

class ViewSimulatorTest : public ::testing::Test {
 protected:
  static constexpr double kSigmas = 4.5;  // bound on noise, in standard deviations
  ViewSimulatorTest() : trees_(Forest(PoissonStats(), 200, 21, 3.0)), simulator_(trees_) {}
  std::vector<MapTree> trees_;
  ViewSimulator simulator_;
};

TEST_F(ViewSimulatorTest, DetectionsMatchTruth) {
  ViewOptions options;
  options.max_tilt = 0.5;
  const std::vector<Eigen::Vector3d> poses = simulator_.SamplePoses(60, 20, 2);
  ASSERT_EQ(poses.size(), 60u);
  int detected_true = 0;
  for (size_t v = 0; v < poses.size(); ++v) {
    options.seed = v;
    const SimulatedView view = simulator_.Simulate(poses[v].head<2>(), poses[v].z(), options);
    ASSERT_EQ(view.trees.size(), view.truth_ids.size());
    const Eigen::Vector3d sensor = view.map_from_sensor.translation();
    EXPECT_NEAR(Horizontal(sensor, {poses[v].x(), poses[v].y(), 0}), 0, 1e-9);
    EXPECT_NEAR(YawOf(view.map_from_sensor.linear()), poses[v].z(), 1e-9);
    for (size_t i = 0; i < view.trees.size(); ++i) {
      const Eigen::Vector3d in_map = view.map_from_sensor * view.trees[i].position;
      EXPECT_LE(Horizontal(in_map, sensor), options.range + kSigmas * options.position_noise);
      if (view.truth_ids[i] < 0) {
        continue;
      }
      ++detected_true;
      const MapTree& truth = trees_[view.truth_ids[i]];
      EXPECT_LE(Horizontal(truth.position, sensor), options.range);
      EXPECT_LE(Horizontal(in_map, truth.position), kSigmas * options.position_noise);
      EXPECT_NEAR(in_map.z(), truth.position.z(), kSigmas * options.position_noise);
      EXPECT_NEAR(view.trees[i].dbh, truth.dbh, kSigmas * options.dbh_noise);
    }
  }
  EXPECT_GT(detected_true, 60 * 10);
}

TEST_F(ViewSimulatorTest, MissAndFalseRates) {
  ViewOptions options;
  options.miss_rate = 0.3;
  options.false_rate = 0.2;
  int visible = 0, detected_true = 0, detected_false = 0;
  const std::vector<Eigen::Vector3d> poses = simulator_.SamplePoses(300, 15, 3);
  for (size_t v = 0; v < poses.size(); ++v) {
    options.seed = 1000 + v;
    const SimulatedView view = simulator_.Simulate(poses[v].head<2>(), poses[v].z(), options);
    visible += view.visible_trees;
    for (size_t i = 0; i < view.trees.size(); ++i) {
      if (view.truth_ids[i] >= 0) {
        ++detected_true;
        continue;
      }
      ++detected_false;
      // False stems are not on top of true trees.
      const Eigen::Vector3d in_map = view.map_from_sensor * view.trees[i].position;
      const int nearest = simulator_.grid().Nearest(in_map.head<2>());
      EXPECT_GT(Horizontal(trees_[nearest].position, in_map), 1.0 - kSigmas * 0.05);
    }
  }
  ASSERT_GT(visible, 5000);
  EXPECT_NEAR(1.0 - static_cast<double>(detected_true) / visible, options.miss_rate, 0.03);
  EXPECT_NEAR(static_cast<double>(detected_false) / detected_true, options.false_rate, 0.03);
}

TEST_F(ViewSimulatorTest, OcclusionMatchesBruteForceShadows) {
  ViewOptions options;
  options.miss_rate = 0;
  options.false_rate = 0;
  options.range = 30;
  int total_in_range = 0, total_visible = 0;
  for (const Eigen::Vector3d& pose : simulator_.SamplePoses(20, 30, 4)) {
    const SimulatedView view = simulator_.Simulate(pose.head<2>(), pose.z(), options);
    const std::set<int64_t> seen(view.truth_ids.begin(), view.truth_ids.end());
    EXPECT_EQ(static_cast<int>(seen.size()), view.visible_trees);
    int in_range = 0;
    for (const MapTree& tree : trees_) {
      const Eigen::Vector2d offset = tree.position.head<2>() - pose.head<2>();
      if (offset.norm() > options.range) continue;
      ++in_range;
      bool shadowed = false;  // by the trunk of any nearer tree
      for (const MapTree& other : trees_) {
        const Eigen::Vector2d o = other.position.head<2>() - pose.head<2>();
        if (o.norm() >= offset.norm() || o.norm() <= other.dbh / 2) continue;
        const double gap =
            std::abs(WrapAngle(std::atan2(offset.y(), offset.x()) - std::atan2(o.y(), o.x())));
        shadowed |= gap <= std::asin(other.dbh / 2 / o.norm());
      }
      EXPECT_EQ(seen.count(tree.id) == 0, shadowed) << "tree " << tree.id;
    }
    options.occlusion = false;
    EXPECT_EQ(simulator_.Simulate(pose.head<2>(), pose.z(), options).visible_trees, in_range);
    options.occlusion = true;
    total_in_range += in_range;
    total_visible += view.visible_trees;
  }
  EXPECT_LT(total_visible, 0.95 * total_in_range);  // at 30 m range trunks do hide trees
}

TEST(ViewSimulatorOcclusionTest, TreeBehindThickTrunkIsHidden) {
  std::vector<MapTree> trees(3);
  trees[0] = {0, {5, 0, 0}, 0.6};     // thick trunk 5 m ahead
  trees[1] = {1, {10, 0.2, 0}, 0.3};  // behind it, within its shadow (+-3.4 deg)
  trees[2] = {2, {10, 3, 0}, 0.3};    // beside the shadow
  const ViewSimulator simulator(trees);
  ViewOptions options;
  options.miss_rate = 0;
  options.false_rate = 0;
  for (unsigned seed = 0; seed < 20; ++seed) {
    options.seed = seed;
    const SimulatedView view = simulator.Simulate({0, 0}, 0.3, options);
    EXPECT_EQ(view.visible_trees, 2);
    EXPECT_EQ(std::set<int64_t>(view.truth_ids.begin(), view.truth_ids.end()),
              (std::set<int64_t>{0, 2}));
  }
  options.occlusion = false;
  EXPECT_EQ(simulator.Simulate({0, 0}, 0.3, options).visible_trees, 3);
}

TEST_F(ViewSimulatorTest, TiltedSensorStemAxesPointUpInMap) {
  ViewOptions options;
  options.max_tilt = 80 * kDeg;
  double max_tilt_seen = 0;
  const std::vector<Eigen::Vector3d> poses = simulator_.SamplePoses(40, 20, 5);
  for (size_t v = 0; v < poses.size(); ++v) {
    options.seed = v;
    const SimulatedView view = simulator_.Simulate(poses[v].head<2>(), poses[v].z(), options);
    const Eigen::Matrix3d map_from_sensor = view.map_from_sensor.linear();
    const double tilt = std::acos(std::clamp(map_from_sensor(2, 2), -1.0, 1.0));
    EXPECT_LE(tilt, options.max_tilt + 1e-9);
    max_tilt_seen = std::max(max_tilt_seen, tilt);
    Eigen::Vector3d mean_axis = Eigen::Vector3d::Zero();
    for (const DetectedTree& tree : view.trees) {
      ASSERT_TRUE(tree.HasAxis());
      const Eigen::Vector3d axis_in_map = map_from_sensor * tree.axis;
      EXPECT_LT(std::acos(std::clamp(axis_in_map.z(), -1.0, 1.0)), 10 * kDeg);
      mean_axis += axis_in_map;
    }
    if (view.trees.size() >= 10) {
      EXPECT_LT(std::acos(mean_axis.normalized().z()), 2 * kDeg);
    }
  }
  EXPECT_GT(max_tilt_seen, 40 * kDeg);  // the tilts really are large
}

TEST(ViewSimulator2dMapTest, UnknownZAndDbhStayUnknown) {
  StemMapStatistics stats = PoissonStats();
  stats.has_dbh = false;
  std::vector<MapTree> trees = Forest(stats, 100, 6);
  for (MapTree& tree : trees) tree.position.z() = kUnknown;
  const ViewSimulator simulator(trees);
  ViewOptions options;
  const SimulatedView view = simulator.Simulate({50, 50}, 1.0, options);
  ASSERT_FALSE(view.trees.empty());
  EXPECT_NEAR(view.map_from_sensor.translation().z(), options.sensor_height, 1e-12);
  for (const DetectedTree& tree : view.trees) {
    EXPECT_FALSE(IsKnown(tree.dbh));
    EXPECT_NEAR(tree.position.z(), -options.sensor_height, 4.5 * options.position_noise);
  }
}

TEST_F(ViewSimulatorTest, SameSeedSameView) {
  ViewOptions options;
  options.max_tilt = 0.3;
  options.seed = 77;
  const SimulatedView a = simulator_.Simulate({100, 100}, 0.5, options);
  const SimulatedView b = simulator_.Simulate({100, 100}, 0.5, options);
  options.seed = 78;
  const SimulatedView c = simulator_.Simulate({100, 100}, 0.5, options);
  ASSERT_EQ(a.trees.size(), b.trees.size());
  EXPECT_TRUE(a.map_from_sensor.isApprox(b.map_from_sensor));
  EXPECT_EQ(a.truth_ids, b.truth_ids);
  for (size_t i = 0; i < a.trees.size(); ++i) EXPECT_EQ(a.trees[i].position, b.trees[i].position);
  EXPECT_FALSE(a.map_from_sensor.isApprox(c.map_from_sensor));
  EXPECT_EQ(simulator_.SamplePoses(10, 5, 3), simulator_.SamplePoses(10, 5, 3));
}

TEST_F(ViewSimulatorTest, SamplePosesRespectMarginAndMinTrees) {
  constexpr double kMargin = 25, kRange = 12;
  constexpr int kMinTrees = 25;
  const std::vector<Eigen::Vector3d> poses = SamplePoses(trees_, 50, kMargin, 8, kMinTrees, kRange);
  ASSERT_EQ(poses.size(), 50u);
  const Eigen::Vector2d lo = simulator_.grid().min_corner(), hi = simulator_.grid().max_corner();
  for (const Eigen::Vector3d& pose : poses) {
    EXPECT_GE(pose.x(), lo.x() + kMargin);
    EXPECT_LE(pose.x(), hi.x() - kMargin);
    EXPECT_GE(pose.y(), lo.y() + kMargin);
    EXPECT_LE(pose.y(), hi.y() - kMargin);
    EXPECT_LE(std::abs(pose.z()), M_PI);
    int near = 0;
    for (const MapTree& tree : trees_)
      near += (tree.position.head<2>() - pose.head<2>()).norm() <= kRange;
    EXPECT_GE(near, kMinTrees);
  }
  // Impossible demands give fewer poses, not a hang.
  EXPECT_TRUE(simulator_.SamplePoses(5, kMargin, 8, 100000).empty());
}

TEST_F(ViewSimulatorTest, InvalidInputThrows) {
  ViewOptions options;
  options.range = -1;
  EXPECT_THROW(simulator_.Simulate({0, 0}, 0, options), std::invalid_argument);
  options = {};
  options.miss_rate = 1.5;
  EXPECT_THROW(simulator_.Simulate({0, 0}, 0, options), std::invalid_argument);
  options = {};
  options.max_tilt = 2.0;
  EXPECT_THROW(simulator_.Simulate({0, 0}, 0, options), std::invalid_argument);
  options = {};
  options.false_rate = -0.1;
  EXPECT_THROW(simulator_.Simulate({0, 0}, 0, options), std::invalid_argument);
  EXPECT_THROW(simulator_.Simulate({kUnknown, 0}, 0, {}), std::invalid_argument);
  EXPECT_THROW(simulator_.SamplePoses(5, 150, 1), std::invalid_argument);  // no room left
  EXPECT_THROW(simulator_.SamplePoses(-1, 0, 1), std::invalid_argument);
  std::vector<MapTree> bad = trees_;
  bad[7].position.y() = INFINITY;
  EXPECT_THROW(ViewSimulator{bad}, std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
