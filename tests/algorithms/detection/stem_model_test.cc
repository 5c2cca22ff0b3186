// Stems from clusters: taper fit, per-slice circles, axis, ground point, DBH, cluster splitting.
#include "algorithms/detection/stem_model.h"

#include <gtest/gtest.h>

#include "synthetic_stems.h"

namespace forestmap::algorithms {
namespace {

constexpr double kStemDbhTolerance = 0.01;       // m
constexpr double kStemPositionTolerance = 0.03;  // m

TEST(StemModelTest, TaperFitIsExactOnACubic) {
  std::vector<TaperSample> samples;
  auto d = [](double h) { return 0.4 - 0.03 * h + 0.004 * h * h - 0.001 * h * h * h; };
  for (double h = 0.5; h <= 3.0; h += 0.25) samples.push_back({h, d(h), 1.0});
  const TaperFit fit = FitTaper(samples, 1.3);
  EXPECT_EQ(fit.degree, 3);
  EXPECT_NEAR(fit.diameter, d(1.3), 1e-6);
}

TEST(StemModelTest, TaperFitResistsAnOutlierSliceAndStaysInRange) {
  std::vector<TaperSample> samples;
  for (double h = 0.5; h <= 3.0; h += 0.25) samples.push_back({h, 0.30 - 0.01 * h, 1.0});
  samples[4].diameter = 0.5;  // a branch whorl
  EXPECT_NEAR(FitTaper(samples, 1.3).diameter, 0.287, 0.005);
  // Far outside the slices a polynomial is not trusted: constant or linear only.
  const std::vector<TaperSample> short_stem{{2.0, 0.3, 1}, {2.2, 0.31, 1}};
  const TaperFit fit = FitTaper(short_stem, 1.3);
  EXPECT_EQ(fit.degree, 0);
  EXPECT_GE(fit.diameter, 0.3);
  EXPECT_LE(fit.diameter, 0.31);
  EXPECT_TRUE(std::isnan(FitTaper({}, 1.3).diameter));
}

// Every index of a cloud, as one cluster.
std::vector<std::vector<uint32_t>> OneCluster(size_t n) {
  std::vector<uint32_t> all(n);
  for (uint32_t i = 0; i < n; ++i) all[i] = i;
  return {all};
}

std::vector<float> Heights(const PointCloud& cloud, double ground_z) {
  std::vector<float> h;
  for (const Eigen::Vector3f& p : cloud.points) h.push_back(static_cast<float>(p.z() - ground_z));
  return h;
}

// Flat ground at z = -5 over a 20 x 20 m grid of 1 m pillars.
GroundModel FlatGround(double z) {
  return GroundModel(-10, -10, 1, 20, 20, std::vector<float>(400, static_cast<float>(z)));
}

TEST(StemModelTest, TwoTouchingStemsInOneClusterAreSplit) {
  PointCloud cloud;
  const double xs[2] = {4.0, 4.42};  // radii 0.2 and 0.2: a 2 cm gap
  for (int k = 0; k < 2; ++k) {
    const PointCloud slice = testing::StemSlice(xs[k], 1.0, 0.2, -4.5, -2.0, 3000, 0.003, k);
    cloud.points.insert(cloud.points.end(), slice.points.begin(), slice.points.end());
  }
  StemModelOptions options;
  options.sensor_at_origin = false;
  const StemModelResult result =
      FitStems(cloud.points, Heights(cloud, -5), OneCluster(cloud.size()), FlatGround(-5), options);
  ASSERT_EQ(result.trunks.size(), 2u);
  for (const DetectedTrunk& trunk : result.trunks) {
    const double x = std::abs(trunk.tree.position.x() - xs[0]) < 0.2 ? xs[0] : xs[1];
    EXPECT_NEAR(trunk.tree.position.x(), x, kStemPositionTolerance);
    EXPECT_NEAR(trunk.tree.position.y(), 1.0, kStemPositionTolerance);
    EXPECT_NEAR(trunk.tree.position.z(), -5.0, 1e-6);  // the ground intersection
    EXPECT_NEAR(trunk.tree.dbh, 0.4, kStemDbhTolerance);
    EXPECT_TRUE(trunk.ground_known);
    EXPECT_NEAR(trunk.dbh_height, 1.3, 1e-9);
    EXPECT_GT(trunk.tree.score, 0.3);
    EXPECT_LE(trunk.tree.score, 1.0);
  }
}

TEST(StemModelTest, SingleViewScanGivesGroundPointAndDbh) {
  testing::SyntheticScene scene;
  scene.ground_z = -6;
  scene.stems = {{6.0, 2.0, 0.32, 0.012, 12}};
  const PointCloud scan = testing::CastScan(scene, testing::SyntheticScanner{}, 3);
  PointCloud stem;
  for (const Eigen::Vector3f& p : scan.points) {
    if (std::isfinite(p.x()) && p.z() > -5.5 && p.z() < -3.0) stem.points.push_back(p);
  }
  const StemModelResult result = FitStems(stem.points, Heights(stem, -6), OneCluster(stem.size()),
                                          FlatGround(-6), StemModelOptions{});
  ASSERT_EQ(result.trunks.size(), 1u);
  const DetectedTrunk& trunk = result.trunks[0];
  EXPECT_NEAR(trunk.tree.position.x(), 6.0, kStemPositionTolerance);
  EXPECT_NEAR(trunk.tree.position.y(), 2.0, kStemPositionTolerance);
  EXPECT_NEAR(trunk.tree.dbh, 0.32, kStemDbhTolerance);
  EXPECT_GT(trunk.tree.axis.z(), 0.99);
  EXPECT_NEAR(trunk.breast_height_point.z(), -6 + 1.3, 0.02);
  EXPECT_LT(trunk.arc_coverage, 0.55);  // one side only
  EXPECT_GT(trunk.points_used, 100);
}

TEST(StemModelTest, WithoutGroundThePositionIsTheLowestStemPoint) {
  const PointCloud slice = testing::StemSlice(2, 3, 0.15, 1.1, 1.5, 4000, 0.003, 1);
  StemModelOptions options;
  options.sensor_at_origin = false;
  const StemModelResult result =
      FitStems(slice.points, Heights(slice, 1.1), OneCluster(slice.size()), GroundModel(), options);
  ASSERT_EQ(result.trunks.size(), 1u);
  const DetectedTrunk& trunk = result.trunks[0];
  EXPECT_FALSE(trunk.ground_known);
  EXPECT_TRUE(std::isnan(trunk.ground_z));
  EXPECT_NEAR(trunk.tree.position.z(), 1.1, 0.01);
  EXPECT_NEAR(trunk.tree.dbh, 0.30, kStemDbhTolerance);
  EXPECT_NEAR(trunk.breast_height_point.z(), 1.3, 0.1);  // middle of the slices seen
}

TEST(StemModelTest, BeamDivergenceCompensationShrinksFarStems) {
  const PointCloud slice = testing::StemSlice(10, 0, 0.15, -4.5, -2, 3000, 0.003, 2);
  StemModelOptions options;
  options.sensor_at_origin = false;
  const auto clusters = OneCluster(slice.size());
  const double plain = FitStems(slice.points, Heights(slice, -5), clusters, FlatGround(-5), options)
                           .trunks[0]
                           .tree.dbh;
  options.sensor_at_origin = true;
  options.beam_divergence = 3e-3;
  options.divergence_bias_factor = 0.5;
  options.min_arc_coverage = 0;
  const StemModelResult result =
      FitStems(slice.points, Heights(slice, -5), clusters, FlatGround(-5), options);
  ASSERT_EQ(result.trunks.size(), 1u);
  // 0.5 * 10 m * 3 mrad = 15 mm less.
  EXPECT_NEAR(result.trunks[0].tree.dbh, plain - 0.015, 1e-3);
  // The fit itself is the same (the silhouette prior of a single viewpoint agrees with the arc).
  EXPECT_NEAR(result.trunks[0].raw_dbh, plain, 1e-4);
}

// A blob of clutter (a shrub, foliage) 1.2 m wide: circles fit through it slice by slice, but
// a trunk holds no points inside it.
TEST(StemModelTest, ClutterIsNoStem) {
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-0.6f, 0.6f), z(-4.5f, -2.0f);
    PointCloud clutter;
    for (int i = 0; i < 800; ++i) {
      const float x = 5 + u(rng);  // one draw a statement: the same points with every compiler
      const float y = 5 + u(rng);
      clutter.points.emplace_back(x, y, z(rng));
    }
    const StemModelResult result =
        FitStems(clutter.points, Heights(clutter, -5), OneCluster(clutter.size()), FlatGround(-5),
                 StemModelOptions{});
    EXPECT_TRUE(result.trunks.empty())
        << "seed " << seed << ": a stem of DBH " << result.trunks[0].tree.dbh << " m";
  }
}

}  // namespace
}  // namespace forestmap::algorithms
