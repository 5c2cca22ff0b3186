// Removal of invalid returns, origin duplicates and the drone's own body.
#include "algorithms/detection/scan_filter.h"

#include <gtest/gtest.h>

#include <limits>

namespace forestmap::algorithms {
namespace {

TEST(ScanFilterTest, RemovesInvalidOriginAndSelfReturns) {
  PointCloud cloud;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud.points = {{nan, nan, nan}, {0, 0, 0},    {0, 0, 0},   {0.1f, 0.2f, -0.1f},
                  {5, 0, -2},      {0, 30, -10}, {0.3f, 0, 0}};
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  ScanFilterOptions options;
  options.self_radius = 0.35;
  options.max_range = 20;
  const ScanFilterResult result = FilterScan(cloud, options);
  EXPECT_EQ(result.invalid, 1u);
  EXPECT_EQ(result.origin_duplicates, 2u);
  EXPECT_EQ(result.self_returns, 2u);
  EXPECT_EQ(result.out_of_range, 1u);
  ASSERT_EQ(result.points.size(), 1u);
  EXPECT_EQ(result.source_index[0], 4u);
  EXPECT_EQ(result.points[0], Eigen::Vector3f(5, 0, -2));
}

TEST(ScanFilterTest, NegativeRadiusIsRejected) {
  ScanFilterOptions options;
  options.self_radius = -1;
  EXPECT_THROW(FilterScan(PointCloud{}, options), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
