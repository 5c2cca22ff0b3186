// Stem layer extraction and the grid DBSCAN in the horizontal plane.
#include "algorithms/detection/stem_clustering.h"

#include <gtest/gtest.h>

#include <random>

#include "synthetic_stems.h"

namespace forestmap::algorithms {
namespace {

TEST(StemClusteringTest, LayerWithAndWithoutGround) {
  const std::vector<float> heights{-0.1f, 0.2f, 0.5f, 1.3f, 2.9f, 3.5f};
  StemLayerOptions options;
  EXPECT_EQ(ExtractStemLayer(heights, true, options), (std::vector<uint32_t>{2, 3, 4}));
  // Without ground the heights start at the lowest point: the layer is [0, 2.5].
  EXPECT_EQ(ExtractStemLayer(heights, false, options), (std::vector<uint32_t>{1, 2, 3}));
  options.max_height = 0.2;
  EXPECT_THROW(ExtractStemLayer(heights, true, options), std::invalid_argument);
}

TEST(StemClusteringTest, SeparatesNearbyStemsAndDropsNoise) {
  std::vector<Eigen::Vector3f> points;
  const double centres[3][2] = {{0, 0}, {0.6, 0}, {5, 5}};  // 0.6 m apart: 0.25 m gap
  for (int k = 0; k < 3; ++k) {
    const PointCloud slice =
        testing::StemSlice(centres[k][0], centres[k][1], 0.17, 0.5, 3.0, 800, 0.005, k);
    points.insert(points.end(), slice.points.begin(), slice.points.end());
  }
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> far(20, 40);
  for (int i = 0; i < 30; ++i) points.emplace_back(far(rng), far(rng), 1.0f);  // sparse noise
  std::vector<uint32_t> all(points.size());
  for (uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  const StemClusters clusters = ClusterStems(points, all, StemClusterOptions{});
  ASSERT_EQ(clusters.clusters.size(), 3u);
  for (const auto& cluster : clusters.clusters) EXPECT_EQ(cluster.size(), 800u);
  EXPECT_EQ(clusters.noise_points, 30u);
  // Each cluster is one stem: all its points come from the same 800-point block.
  for (const auto& cluster : clusters.clusters) {
    const uint32_t block = cluster.front() / 800;
    for (uint32_t i : cluster) EXPECT_EQ(i / 800, block);
  }
}

TEST(StemClusteringTest, ClustersOnlyTheGivenIndices) {
  const PointCloud slice = testing::StemSlice(1, 1, 0.2, 0, 1, 100, 0.0, 1);
  const std::vector<uint32_t> half{0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28};
  StemClusterOptions options;
  options.eps = 0.3;
  const StemClusters clusters = ClusterStems(slice.points, half, options);
  ASSERT_EQ(clusters.clusters.size(), 1u);
  EXPECT_EQ(clusters.clusters[0].size(), half.size());
  EXPECT_TRUE(ClusterStems(slice.points, {}, options).clusters.empty());
}

}  // namespace
}  // namespace forestmap::algorithms
