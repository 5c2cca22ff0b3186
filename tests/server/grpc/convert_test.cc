#include "server/grpc/convert.h"

#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace forestmap::server {
namespace {

using google::protobuf::util::MessageDifferencer;

constexpr double kRotationTolerance = 1e-12;  // rotation matrix entries after a round trip

storage::TreeRecord Record(std::optional<int64_t> id, double x, double y, std::optional<double> z,
                           std::optional<double> dbh,
                           std::map<std::string, std::string> attributes = {}) {
  storage::TreeRecord tree;
  tree.id = id;
  tree.x = x;
  tree.y = y;
  tree.z = z;
  tree.dbh = dbh;
  tree.attributes = std::move(attributes);
  return tree;
}

TEST(ConvertTest, MapInfoToProtoCopiesEveryField) {
  storage::MapInfo info;
  info.name = "plot-7";
  info.description = "Boreal plot";
  info.crs = "EPSG:32612";
  info.version = 5;
  info.tree_count = 1234;
  info.extent = storage::Extent{-1.5, 2.25, 100.125, 200.5};
  info.created_unix_ms = 1700000000123;
  info.updated_unix_ms = 1700000000456;

  const v1::Map map = ToProto(info);
  EXPECT_EQ(map.name(), "plot-7");
  EXPECT_EQ(map.description(), "Boreal plot");
  EXPECT_EQ(map.crs(), "EPSG:32612");
  EXPECT_EQ(map.version(), 5);
  EXPECT_EQ(map.tree_count(), 1234);
  ASSERT_TRUE(map.has_extent());
  EXPECT_EQ(map.extent().min_x(), -1.5);
  EXPECT_EQ(map.extent().min_y(), 2.25);
  EXPECT_EQ(map.extent().max_x(), 100.125);
  EXPECT_EQ(map.extent().max_y(), 200.5);
  EXPECT_EQ(map.created_unix_ms(), 1700000000123);
  EXPECT_EQ(map.updated_unix_ms(), 1700000000456);
}

TEST(ConvertTest, EmptyMapHasNoExtent) {
  storage::MapInfo info;
  info.name = "empty";
  EXPECT_FALSE(ToProto(info).has_extent());
}

TEST(ConvertTest, TreeRoundTripKeepsOptionalFieldsAndBits) {
  const std::vector<storage::TreeRecord> trees = {
      Record(7, 1.0 / 3.0, 1e-300, 0.1 + 0.2, 0.3, {{"species", "Picea abies"}, {"h", "21.5"}}),
      Record(std::nullopt, 654321.123456789, 7012345.987654321, std::nullopt, std::nullopt),
      Record(0, -3.5, 4.0, -12.75, std::nullopt),
      Record(9007199254740993, 5.0, 6.0, std::nullopt, 0.0),
  };
  std::vector<storage::TreeRecord> with_nulls = trees;
  with_nulls[0].null_attributes = {"LI", "LO"};  // survey columns unknown for this tree
  with_nulls[1].null_attributes = {"BT"};
  for (const storage::TreeRecord& tree : with_nulls) {
    const v1::Tree proto = ToProto(tree);
    EXPECT_EQ(static_cast<size_t>(proto.null_attributes_size()), tree.null_attributes.size());
    EXPECT_EQ(proto.has_id(), tree.id.has_value());
    EXPECT_EQ(proto.has_z(), tree.z.has_value());
    EXPECT_EQ(proto.has_dbh(), tree.dbh.has_value());
    EXPECT_EQ(FromProto(proto), tree);  // doubles compared exactly
    // And the other way round, through the wire format.
    v1::Tree parsed;
    ASSERT_TRUE(parsed.ParseFromString(proto.SerializeAsString()));
    EXPECT_TRUE(MessageDifferencer::Equals(ToProto(FromProto(parsed)), proto));
  }
}

TEST(ConvertTest, BoxRoundTrip) {
  const storage::Extent extent{-10.5, -20.25, 30.125, 40.0};
  const storage::Extent back = FromProto(ToProto(extent));
  EXPECT_EQ(back.min_x, extent.min_x);
  EXPECT_EQ(back.min_y, extent.min_y);
  EXPECT_EQ(back.max_x, extent.max_x);
  EXPECT_EQ(back.max_y, extent.max_y);
}

TEST(ConvertTest, SurveyBoundaryRoundTripKeepsHolesAndBits) {
  storage::BoundaryPolygon polygon;
  polygon.outer = {{0.1, -0.2}, {100.30000000000001, 0}, {100, 1e6 + 0.5}};
  polygon.holes = {{{1, 1}, {2, 1}, {2, 2}}, {{5, 5}, {6, 5}, {6, 6}, {5, 6}}};
  storage::BoundaryPolygon triangle;
  triangle.outer = {{7, 7}, {8, 7}, {8, 8}};
  const storage::Boundary boundary = {polygon, triangle};
  const v1::SurveyBoundary message = ToProto(boundary);
  ASSERT_EQ(message.polygons_size(), 2);
  EXPECT_EQ(message.polygons(0).holes_size(), 2);
  EXPECT_EQ(message.polygons(0).outer().vertices(2).y(), 1e6 + 0.5);
  EXPECT_EQ(FromProto(message), boundary);
  EXPECT_TRUE(FromProto(v1::SurveyBoundary()).empty());
}

TEST(ConvertTest, DetectedTreeAbsentFieldsBecomeUnknown) {
  v1::DetectedTree bare;
  bare.mutable_position()->set_x(1);
  bare.mutable_position()->set_y(2);
  bare.mutable_position()->set_z(3);
  const algorithms::DetectedTree a = FromProto(bare);
  EXPECT_EQ(a.position, Eigen::Vector3d(1, 2, 3));
  EXPECT_TRUE(std::isnan(a.dbh));
  EXPECT_TRUE(std::isnan(a.score));
  EXPECT_EQ(a.axis, Eigen::Vector3d::Zero());
  EXPECT_FALSE(a.HasAxis());

  v1::DetectedTree full = bare;
  full.set_dbh(0.31);
  full.set_score(0.9);
  full.mutable_axis()->set_z(-2.0);  // any length, any sign
  const algorithms::DetectedTree b = FromProto(full);
  EXPECT_EQ(b.dbh, 0.31);
  EXPECT_EQ(b.score, 0.9);
  EXPECT_EQ(b.axis, Eigen::Vector3d(0, 0, -1));
  EXPECT_TRUE(b.HasAxis());
}

TEST(ConvertTest, PoseRoundTripOnRandomPoses) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-1000, 1000);
  std::normal_distribution<double> gauss;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(gauss(rng), gauss(rng), gauss(rng), gauss(rng)).normalized();
    algorithms::Pose3 pose = algorithms::Pose3::Identity();
    pose.linear() = q.toRotationMatrix();
    pose.translation() = Eigen::Vector3d(coord(rng), coord(rng), coord(rng));

    const v1::Pose proto = ToProto(pose);
    const double norm = std::sqrt(
        proto.rotation().x() * proto.rotation().x() + proto.rotation().y() * proto.rotation().y() +
        proto.rotation().z() * proto.rotation().z() + proto.rotation().w() * proto.rotation().w());
    EXPECT_NEAR(norm, 1.0, kRotationTolerance);
    const algorithms::Pose3 back = FromProto(proto);
    EXPECT_EQ(back.translation(), pose.translation());  // bit-identical
    EXPECT_TRUE(back.linear().isApprox(pose.linear(), kRotationTolerance)) << "pose " << i;
  }
}

TEST(ConvertTest, PoseDefaultsAndNormalisation) {
  EXPECT_TRUE(FromProto(v1::Pose()).isApprox(algorithms::Pose3::Identity()));
  v1::Pose pose;
  pose.mutable_rotation()->set_z(1.0005);  // slightly long: normalised
  const algorithms::Pose3 p = FromProto(pose);
  const Eigen::Matrix3d half_turn =
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_TRUE(p.linear().isApprox(half_turn, kRotationTolerance));
  EXPECT_EQ(p.translation(), Eigen::Vector3d::Zero());
}

TEST(ConvertTest, RelocalizeRequestToQuery) {
  v1::RelocalizeRequest request;
  request.set_name("m");
  for (int i = 0; i < 4; ++i) request.add_trees()->mutable_position()->set_x(i);
  EXPECT_EQ(FromProto(request).trees.size(), 4u);
  EXPECT_FALSE(FromProto(request).gravity.has_value());
  EXPECT_FALSE(FromProto(request).prior.has_value());

  request.mutable_gravity()->set_z(-9.81);
  request.mutable_prior()->set_radius_m(25);
  request.mutable_prior()->set_x(10);
  request.mutable_prior()->set_y(20);
  const algorithms::RelocalizeQuery query = FromProto(request);
  ASSERT_TRUE(query.gravity.has_value());
  EXPECT_EQ(*query.gravity, Eigen::Vector3d(0, 0, -1));
  ASSERT_TRUE(query.prior.has_value());
  EXPECT_EQ(query.prior->radius, 25);
  EXPECT_EQ(query.prior->map_from_sensor.translation().head<2>(), Eigen::Vector2d(10, 20));
}

TEST(ConvertTest, RelocalizeResultToResponse) {
  algorithms::RelocalizeResult result;
  result.status = algorithms::RelocalizeStatus::kLocalized;
  result.map_from_sensor = algorithms::PoseFromXyzYaw(1, 2, 3, -0.25);
  result.inliers = 2;
  result.matches = {{0, 101, 0.125}, {3, 205, 0.25}};
  result.rmse = 0.2;
  result.confidence = 0.8;
  result.detail = "fine";

  const v1::RelocalizeResponse response = ToProto(result);
  EXPECT_EQ(response.status(), v1::RelocalizeResponse::STATUS_LOCALIZED);
  ASSERT_TRUE(response.has_map_from_sensor());
  EXPECT_TRUE(FromProto(response.map_from_sensor()).isApprox(result.map_from_sensor, 1e-12));
  EXPECT_EQ(response.inliers(), 2);
  ASSERT_EQ(response.matches_size(), 2);
  EXPECT_EQ(response.matches(1).query_index(), 3);
  EXPECT_EQ(response.matches(1).map_tree_id(), 205);
  EXPECT_EQ(response.matches(1).distance_m(), 0.25);
  EXPECT_EQ(response.rmse_m(), 0.2);
  EXPECT_EQ(response.confidence(), 0.8);
  EXPECT_EQ(response.detail(), "fine");

  result.status = algorithms::RelocalizeStatus::kAmbiguous;
  EXPECT_EQ(ToProto(result).status(), v1::RelocalizeResponse::STATUS_AMBIGUOUS);
  EXPECT_FALSE(ToProto(result).has_map_from_sensor());  // a pose only when localized
  result.status = algorithms::RelocalizeStatus::kNotFound;
  EXPECT_EQ(ToProto(result).status(), v1::RelocalizeResponse::STATUS_NOT_FOUND);
  EXPECT_FALSE(ToProto(result).has_map_from_sensor());

  // A view at the map's edge: how much of it the map covers, and why too little is no answer.
  result.reason = algorithms::RelocalizeReason::kOutsideCoverage;
  result.coverage_share = 0.375;
  result.trees_in_coverage = 8;
  const v1::RelocalizeResponse edge = ToProto(result);
  EXPECT_EQ(edge.reason(), v1::RelocalizeResponse::REASON_OUTSIDE_COVERAGE);
  EXPECT_EQ(edge.coverage_share(), 0.375);
  EXPECT_EQ(edge.trees_in_coverage(), 8);
}

TEST(ConvertTest, ObserveRequestToCall) {
  v1::ObserveRequest request;
  request.set_name("shared");
  request.set_source("drone-7");
  request.set_base_version(4);
  v1::ObservationFrame* posed = request.add_frames();
  posed->set_frame_id(11);
  *posed->mutable_map_from_sensor() = ToProto(algorithms::PoseFromXyzYaw(5, 6, 1.5, 0.25));
  v1::DetectedTree* tree = posed->add_trees();
  tree->mutable_position()->set_x(2);
  tree->set_dbh(0.3);
  v1::ObservationFrame* lost = request.add_frames();
  lost->set_frame_id(12);
  lost->mutable_gravity()->set_z(-9.81);

  ObserveCall call = FromProto(request);
  EXPECT_EQ(call.map_name, "shared");
  EXPECT_EQ(call.source, "drone-7");
  EXPECT_FALSE(call.base_version.has_value());  // MERGE (the default): the base does not count
  ASSERT_EQ(call.frames.size(), 2u);
  EXPECT_TRUE(call.frames[0].has_pose);
  EXPECT_EQ(call.frames[0].observations.source, "drone-7");
  EXPECT_EQ(call.frames[0].observations.frame_id, 11);
  EXPECT_TRUE(call.frames[0].observations.map_from_sensor.isApprox(
      algorithms::PoseFromXyzYaw(5, 6, 1.5, 0.25), 1e-12));
  ASSERT_EQ(call.frames[0].observations.trees.size(), 1u);
  EXPECT_EQ(call.frames[0].observations.trees[0].dbh, 0.3);
  EXPECT_FALSE(call.frames[0].gravity.has_value());
  EXPECT_FALSE(call.frames[1].has_pose);
  EXPECT_EQ(call.frames[1].gravity, Eigen::Vector3d(0, 0, -1));  // (0, 0, -9.81) normalised

  request.set_conflict_policy(v1::CONFLICT_POLICY_REJECT_IF_STALE);
  call = FromProto(request);
  EXPECT_EQ(call.base_version, 4);
}

TEST(ConvertTest, ObserveOutcomeToResponse) {
  ObserveOutcome outcome;
  outcome.map.name = "shared";
  outcome.map.version = 9;
  FrameOutcome merged;
  merged.frame_id = 11;
  merged.merged = true;
  merged.relocalized = true;
  merged.map_from_sensor = algorithms::PoseFromXyzYaw(5, 6, 1.5, 0.25);
  merged.counts = {4, 3, 2, 1};
  FrameOutcome skipped;
  skipped.frame_id = 12;
  skipped.detail = "the frame has no trees";
  outcome.frames = {merged, skipped};

  const v1::ObserveResponse response = ToProto(outcome);
  EXPECT_EQ(response.map_version(), 9);
  EXPECT_EQ(response.map().name(), "shared");
  ASSERT_EQ(response.frames_size(), 2);
  const v1::FrameResult& first = response.frames(0);
  EXPECT_EQ(first.frame_id(), 11);
  EXPECT_EQ(first.status(), v1::FrameResult::STATUS_MERGED);
  EXPECT_TRUE(first.relocalized());
  EXPECT_TRUE(FromProto(first.map_from_sensor()).isApprox(merged.map_from_sensor, 1e-12));
  EXPECT_EQ(first.trees_associated(), 4);
  EXPECT_EQ(first.trees_added(), 3);
  EXPECT_EQ(first.trees_promoted(), 2);
  EXPECT_EQ(first.trees_ignored(), 1);
  const v1::FrameResult& second = response.frames(1);
  EXPECT_EQ(second.frame_id(), 12);
  EXPECT_EQ(second.status(), v1::FrameResult::STATUS_SKIPPED);
  EXPECT_EQ(second.detail(), "the frame has no trees");
  EXPECT_FALSE(second.has_map_from_sensor());
  EXPECT_EQ(response.server_time_ms(), 0);  // the service's to fill in
}

}  // namespace
}  // namespace forestmap::server
