// Stored rows as the algorithms see them and back (server/app/tree_records.h): unknown values are
// std::nullopt in storage and NaN in algorithms, both ways, and nothing else changes.

#include "server/app/tree_records.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

namespace forestmap::server {
namespace {

TEST(TreeRecordsTest, MapTreeUsesNanForUnknownValues) {
  storage::TreeRecord tree;
  tree.id = 3;
  tree.x = 1;
  tree.y = 2;
  tree.z = 3.5;
  tree.dbh = 0.25;
  const algorithms::MapTree known = ToMapTree(tree);
  EXPECT_EQ(known.id, 3);
  EXPECT_EQ(known.position, Eigen::Vector3d(1, 2, 3.5));
  EXPECT_EQ(known.dbh, 0.25);
  tree.z.reset();
  tree.dbh.reset();
  const algorithms::MapTree unknown = ToMapTree(tree);
  EXPECT_TRUE(std::isnan(unknown.position.z()));
  EXPECT_TRUE(std::isnan(unknown.dbh));
}

TEST(TreeRecordsTest, ObservationRowRoundTripKeepsEveryFieldAndUnknowns) {
  storage::ObservationRecord row;
  row.tree_id = 17;
  row.source = "drone-2";
  row.frame_id = 40;
  row.detection_index = 3;
  row.x = 12.25;
  row.y = -7.5;
  row.z = 1.375;
  row.dbh = 0.31;
  row.weight_xy = 400;
  row.weight_dbh = 2500;
  row.sensor_x = 10;
  row.sensor_y = -2;
  row.sensor_z = 1.5;
  row.prior = true;
  const algorithms::TreeObservation seen = ToTreeObservation(row);
  EXPECT_EQ(seen.tree_id, 17);
  EXPECT_EQ(seen.source, "drone-2");
  EXPECT_EQ(seen.position, Eigen::Vector3d(12.25, -7.5, 1.375));
  EXPECT_EQ(seen.sensor_position, Eigen::Vector3d(10, -2, 1.5));
  EXPECT_TRUE(seen.prior);
  EXPECT_EQ(ToObservationRecord(seen), row);  // id and version are the store's: both 0 here

  row.z.reset();
  row.dbh.reset();
  const algorithms::TreeObservation unknown = ToTreeObservation(row);
  EXPECT_TRUE(std::isnan(unknown.position.z()));
  EXPECT_TRUE(std::isnan(unknown.dbh));
  EXPECT_EQ(ToObservationRecord(unknown), row);
}

TEST(TreeRecordsTest, MergedTreeBecomesARowWithItsSurveyColumns) {
  algorithms::TreeEstimate tree;
  tree.id = 9;
  tree.position = Eigen::Vector3d(3, 4, algorithms::kUnknown);
  tree.dbh = 0.4;
  tree.position_sigma = 0.05;
  tree.observations = 6;
  tree.status = algorithms::TreeStatus::kConfirmed;
  const storage::TreeRecord row = ToTreeRecord(tree, {{"species", "pine"}}, {"height"});
  EXPECT_EQ(row.id, 9);
  EXPECT_EQ(row.x, 3);
  EXPECT_EQ(row.y, 4);
  EXPECT_FALSE(row.z.has_value());
  EXPECT_EQ(row.dbh, 0.4);
  EXPECT_EQ(row.position_sigma, 0.05);
  EXPECT_FALSE(row.dbh_sigma.has_value());
  EXPECT_EQ(row.observations, 6);
  EXPECT_EQ(row.status, storage::TreeStatus::kConfirmed);
  EXPECT_EQ(row.attributes.at("species"), "pine");
  EXPECT_EQ(row.null_attributes.count("height"), 1u);
  tree.status = algorithms::TreeStatus::kCandidate;
  EXPECT_EQ(ToTreeRecord(tree, {}).status, storage::TreeStatus::kCandidate);
}

}  // namespace
}  // namespace forestmap::server
