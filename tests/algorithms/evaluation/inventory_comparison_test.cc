// One-to-one links and the survey figures against hand-computed truth.
#include "algorithms/evaluation/inventory_comparison.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

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
  EXPECT_DOUBLE_EQ(*r.completeness, 3.0 / 4.0);
  EXPECT_DOUBLE_EQ(*r.commission, 2.0 / 5.0);
  EXPECT_NEAR(*r.position_rmse, std::sqrt((0.0 + 0.01 + 0.09) / 3), 1e-12);
  EXPECT_NEAR(*r.bias_x, 0.1 / 3, 1e-12);
  EXPECT_NEAR(*r.bias_y, 0.3 / 3, 1e-12);
  ASSERT_EQ(r.dbh_pairs, 2);  // tree 4 has no reference DBH
  EXPECT_NEAR(*r.dbh_rmse, std::sqrt((0.01 * 0.01 + 0.03 * 0.03) / 2), 1e-12);
  EXPECT_NEAR(*r.dbh_bias, (0.01 - 0.03) / 2, 1e-12);
  // Classes of 10 cm: [10, 20) holds trees 1 and 3 (one linked), [20, 30) tree 2.
  ASSERT_EQ(r.omission_by_dbh.size(), 2u);
  EXPECT_EQ(r.omission_by_dbh[0].reference_trees, 2);
  EXPECT_EQ(r.omission_by_dbh[0].linked, 1);
  EXPECT_DOUBLE_EQ(r.omission_by_dbh[0].omission, 0.5);
  EXPECT_EQ(r.omission_by_dbh[1].linked, 1);
  EXPECT_EQ(r.reference_without_dbh, 1);
  EXPECT_EQ(r.reference_without_dbh_linked, 1);  // tree 4
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

// The greedy linking as it was first written: every pair, sorted (LinkBefore), taken in order.
std::vector<InventoryLink> BruteForceLinks(const std::vector<DetectedTree>& detected,
                                           const std::vector<MapTree>& reference, double distance) {
  std::vector<InventoryLink> candidates;
  for (size_t d = 0; d < detected.size(); ++d) {
    for (size_t r = 0; r < reference.size(); ++r) {
      const double gap = LinkGap(detected[d], reference[r]);
      if (gap <= distance) candidates.push_back({int(d), int(r), gap});
    }
  }
  std::sort(candidates.begin(), candidates.end(), LinkBefore);
  std::vector<bool> d_used(detected.size()), r_used(reference.size());
  std::vector<InventoryLink> links;
  for (const InventoryLink& c : candidates) {
    if (d_used[c.detected] || r_used[c.reference]) continue;
    d_used[c.detected] = r_used[c.reference] = true;
    links.push_back(c);
  }
  return links;
}

// Random inventories, some on a coarse grid (many pairs at exactly equal distances, and pairs at
// exactly the link distance), some with large projected coordinates: the k-d tree linking gives
// the very links of the brute force.
TEST(InventoryComparisonTest, LinkingEqualsTheBruteForceIncludingTies) {
  std::mt19937 rng(2024);
  constexpr int kTrials = 60;
  int tied_trials = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    const bool grid = trial % 2 == 0;
    const double offset = trial % 3 == 0 ? 5.1e6 : 0.0;  // UTM-like northing
    const double side = 5 + trial % 20;                  // m
    std::uniform_real_distribution<double> coordinate(0, side);
    std::uniform_int_distribution<int> cell(0, static_cast<int>(side) * 2);
    const auto position = [&]() {
      // On a 0.5 m grid, distances 0.5, 0.7071..., 1.0 repeat exactly.
      if (grid) return Eigen::Vector3d(offset + 0.5 * cell(rng), offset + 0.5 * cell(rng), 0);
      return Eigen::Vector3d(offset + coordinate(rng), offset + coordinate(rng), 0);
    };
    std::vector<DetectedTree> detected(std::uniform_int_distribution<int>(0, 80)(rng));
    std::vector<MapTree> reference(std::uniform_int_distribution<int>(0, 80)(rng));
    for (DetectedTree& tree : detected) tree.position = position();
    for (size_t i = 0; i < reference.size(); ++i) {
      reference[i] = {int64_t(i), position(), 0.2};
    }
    const double distance = grid ? 1.0 : 0.8;
    const std::vector<InventoryLink> expected = BruteForceLinks(detected, reference, distance);
    const std::vector<InventoryLink> links = LinkOneToOne(detected, reference, distance);
    ASSERT_EQ(links.size(), expected.size()) << "trial " << trial;
    for (size_t i = 0; i < links.size(); ++i) {
      EXPECT_EQ(links[i].detected, expected[i].detected) << "trial " << trial << " link " << i;
      EXPECT_EQ(links[i].reference, expected[i].reference) << "trial " << trial << " link " << i;
      EXPECT_EQ(links[i].distance, expected[i].distance) << "trial " << trial << " link " << i;
    }
    for (size_t i = 1; i < expected.size(); ++i) {
      tied_trials += expected[i].distance == expected[i - 1].distance;
    }
    const InventoryComparison comparison = CompareInventories(detected, reference, {distance});
    ASSERT_EQ(comparison.links.size(), expected.size());
  }
  EXPECT_GT(tied_trials, kTrials);  // the grid trials really had ties to break
}

// A pair exactly at the link distance is linked (<=), also far from the origin.
TEST(InventoryComparisonTest, LinksAPairAtExactlyTheLinkDistance) {
  const std::vector<MapTree> reference = {{1, {500000.0, 5100000.0, kUnknown}, 0.2}};
  const std::vector<DetectedTree> detected = {Detection(500000.5, 5100000.0, 0.2)};
  EXPECT_EQ(CompareInventories(detected, reference, {0.5}).links.size(), 1u);
  EXPECT_EQ(CompareInventories(detected, reference, {0.4999}).links.size(), 0u);
}

// A DBH on a class bound is in the class it starts (0.30 m: 30-40 cm, not 20-30 cm).
TEST(InventoryComparisonTest, DbhOnAClassBoundStartsTheClass) {
  const std::vector<MapTree> reference = {{1, {0, 0, kUnknown}, 0.30}, {2, {9, 0, kUnknown}, 0.7}};
  const InventoryComparison r = CompareInventories({}, reference);
  ASSERT_EQ(r.omission_by_dbh.size(), 2u);
  EXPECT_DOUBLE_EQ(r.omission_by_dbh[0].min_dbh, 0.3);
  EXPECT_DOUBLE_EQ(r.omission_by_dbh[1].min_dbh, 0.7);
}

// Nothing to measure gives no figure rather than 0.
TEST(InventoryComparisonTest, FiguresOverNothingAreUnknownNotZero) {
  const std::vector<MapTree> reference = {{1, {0, 0, kUnknown}, 0.2}};
  const std::vector<DetectedTree> far = {Detection(50, 0, 0.2)};
  const InventoryComparison none = CompareInventories(far, reference);
  EXPECT_TRUE(none.links.empty());
  EXPECT_EQ(none.completeness, 0.0);  // a reference tree, not linked: 0 is a measurement
  EXPECT_EQ(none.commission, 1.0);
  EXPECT_FALSE(none.position_rmse.has_value());
  EXPECT_FALSE(none.bias_x.has_value());
  EXPECT_FALSE(none.dbh_rmse.has_value());
  EXPECT_FALSE(none.dbh_bias.has_value());
  const InventoryComparison empty_reference = CompareInventories(far, {});
  EXPECT_FALSE(empty_reference.completeness.has_value());
  const InventoryComparison no_detections = CompareInventories({}, reference);
  EXPECT_FALSE(no_detections.commission.has_value());
  EXPECT_EQ(no_detections.completeness, 0.0);
}

// Completeness over the visible reference trees of a simulation.
TEST(InventoryComparisonTest, CompletenessOverASubset) {
  const std::vector<MapTree> reference = {{1, {0, 0, kUnknown}, 0.2},
                                          {2, {10, 0, kUnknown}, 0.2},
                                          {3, {20, 0, kUnknown}, 0.2},
                                          {4, {30, 0, kUnknown}, 0.2}};
  const std::vector<DetectedTree> detected = {Detection(0, 0, 0.2), Detection(30, 0, 0.2)};
  const InventoryComparison r = CompareInventories(detected, reference);
  const SubsetCompleteness visible = CompletenessOver(r, {true, false, false, true});
  EXPECT_EQ(visible.reference_trees, 2);
  EXPECT_EQ(visible.linked, 2);
  EXPECT_EQ(visible.completeness, 1.0);
  EXPECT_DOUBLE_EQ(*r.completeness, 0.5);
  EXPECT_FALSE(CompletenessOver(r, {false, false, false, false}).completeness.has_value());
}

}  // namespace
}  // namespace forestmap::algorithms
