// Pillar ground segmentation and the height model, against ray-cast scenes with exact ground.
#include "algorithms/detection/ground_model.h"

#include <gtest/gtest.h>

#include "synthetic_stems.h"

namespace forestmap::algorithms {
namespace {

using testing::CastScan;
using testing::SyntheticScanner;
using testing::SyntheticScene;

std::vector<Eigen::Vector3f> Valid(const PointCloud& cloud) {
  std::vector<Eigen::Vector3f> points;
  for (const Eigen::Vector3f& p : cloud.points) {
    if (std::isfinite(p.x())) points.push_back(p);
  }
  return points;
}

SyntheticScene Stand(double slope_x) {
  SyntheticScene scene;
  scene.ground_z = -8;
  scene.slope_x = slope_x;
  for (int i = 0; i < 12; ++i) {
    const double a = 0.5 * i, r = 5.0 + 1.3 * i;
    scene.stems.push_back({r * std::cos(a), r * std::sin(a), 0.2 + 0.02 * i, 0.01, 10});
  }
  return scene;
}

// Heights above ground within 10 cm for every point within 25 m, on flat and 20-degree slopes.
void ExpectTrueHeights(const SyntheticScene& scene) {
  const std::vector<Eigen::Vector3f> points = Valid(CastScan(scene, SyntheticScanner{}, 1));
  const GroundSegmentation ground = SegmentGround(points, GroundOptions{});
  ASSERT_TRUE(ground.ground_known);
  EXPECT_TRUE(ground.model.known());
  int checked = 0, wrong = 0, stem_as_ground = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    if (p.head<2>().norm() > 25) continue;
    const double truth = p.z() - testing::GroundZ(scene, p.x(), p.y());
    ++checked;
    wrong += std::abs(ground.height[i] - truth) > 0.1;
    stem_as_ground += truth > 0.5 && ground.is_ground[i];
  }
  EXPECT_GT(checked, 5000);
  EXPECT_LT(wrong, checked / 100) << "points with a height error over 10 cm";
  EXPECT_EQ(stem_as_ground, 0);
  EXPECT_GT(ground.ground_points, static_cast<size_t>(checked / 2));
}

TEST(GroundModelTest, FlatGroundHeights) { ExpectTrueHeights(Stand(0.0)); }

TEST(GroundModelTest, SlopedGroundHeights) { ExpectTrueHeights(Stand(std::tan(20 * M_PI / 180))); }

// A drone 10 m up with a +-22.5 deg field of view sees ground only from 24 m on; nearer, the
// lowest thing seen can be a shrub top (here a flat plate 4 m above the ground, 15 m away). The
// beams below it that reached the far ground say the ground there lies lower: with
// sensor_at_origin the plate is no ground and the height under it comes from the ground seen.
TEST(GroundModelTest, FreeBeamsUnderAShrubTopSayItIsNoGround) {
  SyntheticScene scene;
  scene.ground_z = -10;
  SyntheticScanner scanner;
  scanner.min_elevation = -22.5 * M_PI / 180;
  scanner.max_elevation = 22.5 * M_PI / 180;
  std::vector<Eigen::Vector3f> points = Valid(CastScan(scene, scanner, 7));
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) points.emplace_back(15.0f + 0.1f * i, 0.1f * j - 1.0f, -6.0f);
  }
  GroundOptions options;
  const GroundSegmentation plain = SegmentGround(points, options);
  options.sensor_at_origin = true;
  const GroundSegmentation single_view = SegmentGround(points, options);
  ASSERT_TRUE(plain.ground_known && single_view.ground_known);
  EXPECT_GT(plain.model.Height(16, 0), -7.0) << "without the free beams the plate is ground";
  EXPECT_NEAR(single_view.model.Height(16, 0), -10, 0.1);
  EXPECT_NEAR(single_view.model.Height(30, 5), -10, 0.05);  // the ground seen stays
}

TEST(GroundModelTest, TrunkSlicesWithoutGroundLeaveTheGroundUnknown) {
  std::vector<Eigen::Vector3f> points;
  for (int k = 0; k < 13; ++k) {
    const PointCloud slice =
        testing::StemSlice(3.0 * k, -2.0 * k, 0.15 + 0.01 * k, 1.1, 1.5, 4000, 0.01, k);
    points.insert(points.end(), slice.points.begin(), slice.points.end());
  }
  const GroundSegmentation ground = SegmentGround(points, GroundOptions{});
  EXPECT_FALSE(ground.ground_known);
  EXPECT_FALSE(ground.model.known());
  EXPECT_EQ(ground.ground_points, 0u);
  EXPECT_NEAR(ground.reference_z, 1.1, 0.01);
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_FLOAT_EQ(ground.height[i], points[i].z() - static_cast<float>(ground.reference_z));
  }
}

TEST(GroundModelTest, EmptyCloudAndBadOptions) {
  const GroundSegmentation ground = SegmentGround({}, GroundOptions{});
  EXPECT_FALSE(ground.ground_known);
  EXPECT_TRUE(ground.height.empty());
  GroundOptions options;
  options.cell_size = 0;
  EXPECT_THROW(SegmentGround({}, options), std::invalid_argument);
}

TEST(GroundModelTest, ModelInterpolatesBetweenPillars) {
  // Heights z = 0.5 x at the pillar centres of a 4 x 4 grid of 1 m pillars.
  std::vector<float> heights;
  for (int iy = 0; iy < 4; ++iy) {
    for (int ix = 0; ix < 4; ++ix) heights.push_back(0.5f * (ix + 0.5f));
  }
  const GroundModel model(0, 0, 1, 4, 4, heights);
  EXPECT_NEAR(model.Height(1.7, 2.2), 0.85, 1e-6);
  EXPECT_NEAR(model.Height(0.5, 0.5), 0.25, 1e-6);
  EXPECT_TRUE(std::isnan(GroundModel().Height(0, 0)));
}

}  // namespace
}  // namespace forestmap::algorithms
