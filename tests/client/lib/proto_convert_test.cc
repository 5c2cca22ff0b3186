#include "client/lib/proto_convert.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace forestmap::client {
namespace {

TEST(ProtoConvertTest, MapTreeRoundTrip) {
  MapTreeRow full;
  full.id = 42;
  full.x = 123456.789;
  full.y = -0.001;
  full.z = 3.5;
  full.dbh = 0.0;  // a known zero is not "unknown"
  full.attributes = {{"species", "beech"}, {"height_m", "23.6"}};
  EXPECT_EQ(FromProto(ToProto(full)), full);

  MapTreeRow sparse;
  sparse.x = 1;
  sparse.y = 2;
  const v1::Tree tree = ToProto(sparse);
  EXPECT_FALSE(tree.has_id());
  EXPECT_FALSE(tree.has_z());
  EXPECT_FALSE(tree.has_dbh());
  EXPECT_EQ(FromProto(tree), sparse);
}

TEST(ProtoConvertTest, SurveyBoundaryRoundTrip) {
  algorithms::Polygon polygon;
  polygon.outer = {{0.1, -0.2}, {100.30000000000001, 0}, {100, 1e6 + 0.5}};
  polygon.holes = {{{1, 1}, {2, 1}, {2, 2}}};
  const std::vector<algorithms::Polygon> back =
      FromProto(ToProto(std::vector<algorithms::Polygon>{polygon, polygon}));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].outer, polygon.outer);
  EXPECT_EQ(back[1].holes, polygon.holes);
}

TEST(ProtoConvertTest, DetectedTreeLeavesUnknownsUnset) {
  algorithms::DetectedTree tree;
  tree.position = {1, 2, 3};
  v1::DetectedTree message = ToProto(tree);
  EXPECT_EQ(message.position().z(), 3);
  EXPECT_FALSE(message.has_dbh());
  EXPECT_FALSE(message.has_axis());
  EXPECT_FALSE(message.has_score());
  tree.dbh = 0.4;
  tree.axis = {0.1, 0, 0.99};
  tree.score = 0;
  message = ToProto(tree);
  EXPECT_EQ(message.dbh(), 0.4);
  EXPECT_EQ(message.axis().x(), 0.1);
  ASSERT_TRUE(message.has_score());
  EXPECT_EQ(message.score(), 0);
}

TEST(ProtoConvertTest, PoseRoundTrip) {
  algorithms::Pose3 pose = algorithms::Pose3::Identity();
  pose.linear() =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(10, -20, 30);
  const algorithms::Pose3 back = FromProto(ToProto(pose));
  EXPECT_TRUE(back.matrix().isApprox(pose.matrix(), 1e-12));
  // An unset rotation reads as the identity.
  EXPECT_TRUE(FromProto(v1::Pose()).matrix().isApprox(Eigen::Matrix4d::Identity()));
}

}  // namespace
}  // namespace forestmap::client
