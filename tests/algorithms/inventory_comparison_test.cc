// One-to-one links and the survey figures against hand-computed truth.
#include "algorithms/evaluation/inventory_comparison.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace forestmap::algorithms {
namespace {

DetectedTree Detection(double x, double y, double dbh) {
  DetectedTree tree;
  tree.position = Eigen::Vector3d(x, y, 0);
  tree.dbh = dbh;
  return tree;
}

TEST(InventoryComparisonTest, LinksOneToOneAndReportsTheFigures) {
  const std::vector<MapTree> reference = {{1, {0, 0, kUnknown}, 0.10},
                                          {2, {10, 0, kUnknown}, 0.25},
                                          {3, {20, 0, kUnknown}, 0.15},
                                          {4, {30, 0, kUnknown}, kUnknown}};
  // Tree 1: two detections near it, the nearer one links; tree 2: 0.3 m off; tree 3: 0.9 m off
  // (beyond 0.8 m: omitted); tree 4: exact, no DBH.
  const std::vector<DetectedTree> detected = {Detection(0.5, 0, 0.12), Detection(0.1, 0, 0.11),
                                              Detection(10, 0.3, 0.22), Detection(20.9, 0, 0.15),
                                              Detection(30, 0, 0.3)};
  const InventoryComparison r = CompareInventories(detected, reference);
  ASSERT_EQ(r.links.size(), 3u);
  EXPECT_EQ(r.links[0].detected, 4);  // distance 0 first
  EXPECT_EQ(r.links[1].detected, 1);
  EXPECT_EQ(r.links[2].detected, 2);
  EXPECT_DOUBLE_EQ(r.completeness, 3.0 / 4.0);
  EXPECT_DOUBLE_EQ(r.commission, 2.0 / 5.0);
  EXPECT_NEAR(r.position_rmse, std::sqrt((0.0 + 0.01 + 0.09) / 3), 1e-12);
  EXPECT_NEAR(r.bias_x, 0.1 / 3, 1e-12);
  EXPECT_NEAR(r.bias_y, 0.3 / 3, 1e-12);
  ASSERT_EQ(r.dbh_pairs, 2);  // tree 4 has no reference DBH
  EXPECT_NEAR(r.dbh_rmse, std::sqrt((0.01 * 0.01 + 0.03 * 0.03) / 2), 1e-12);
  EXPECT_NEAR(r.dbh_bias, (0.01 - 0.03) / 2, 1e-12);
  // Classes of 10 cm: [10, 20) holds trees 1 and 3 (one linked), [20, 30) tree 2.
  ASSERT_EQ(r.omission_by_dbh.size(), 2u);
  EXPECT_EQ(r.omission_by_dbh[0].reference_trees, 2);
  EXPECT_EQ(r.omission_by_dbh[0].linked, 1);
  EXPECT_DOUBLE_EQ(r.omission_by_dbh[0].omission, 0.5);
  EXPECT_EQ(r.omission_by_dbh[1].linked, 1);
  EXPECT_EQ(r.reference_without_dbh, 1);
}

TEST(InventoryComparisonTest, RegistrationUndoesAKnownMotion) {
  std::vector<MapTree> reference;
  std::vector<DetectedTree> detected;
  Pose3 detected_from_reference = Pose3::Identity();
  detected_from_reference.linear() =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  detected_from_reference.translation() = Eigen::Vector3d(500, -300, 0);
  std::mt19937 rng(14);  // a random plot, 25 x 20 m, fixed seed
  std::uniform_real_distribution<double> x(0, 25), y(0, 20);
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector3d p(x(rng), y(rng), 0);
    reference.push_back({i, {p.x(), p.y(), kUnknown}, 0.1 + 0.01 * (i % 7)});
    detected.push_back(Detection(0, 0, 0.1 + 0.01 * (i % 7)));
    detected.back().position = detected_from_reference * p;
  }
  const Registration registration = RegisterToReference(detected, reference);
  ASSERT_EQ(registration.result.status, RelocalizeStatus::kLocalized) << registration.result.detail;
  for (size_t i = 0; i < detected.size(); ++i) {
    const Eigen::Vector3d back = registration.reference_from_detected * detected[i].position;
    EXPECT_NEAR((back - reference[i].position).head<2>().norm(), 0.0, 1e-3) << i;
  }
}

}  // namespace
}  // namespace forestmap::algorithms
