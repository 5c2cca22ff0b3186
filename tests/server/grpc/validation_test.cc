#include "server/grpc/validation.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <tuple>

#include "server/grpc/convert.h"
#include "server/grpc/map_set.h"
#include "server/grpc/upload_validator.h"
#include "tests/server/grpc/validation_test_util.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

using test::kNaN;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Runs `body`, expects it to throw ErrorType and returns the message.
template <typename ErrorType, typename Body>
std::string ErrorOf(Body&& body) {
  try {
    body();
  } catch (const ErrorType& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
    return "";
  }
  ADD_FAILURE() << "no exception";
  return "";
}

v1::RelocalizeRequest Query(int trees) {
  v1::RelocalizeRequest request;
  request.set_name("plot");
  for (int i = 0; i < trees; ++i) {
    v1::DetectedTree* tree = request.add_trees();
    tree->mutable_position()->set_x(i);
    tree->mutable_position()->set_y(2.0 * i);
  }
  return request;
}

// The field a ValidationError names for the error details (google.rpc.BadRequest).
template <typename Body>
std::string FieldOf(Body&& body) {
  try {
    body();
  } catch (const ValidationError& e) {
    return e.field();
  }
  ADD_FAILURE() << "no ValidationError";
  return "";
}

v1::UploadTreesRequest Header(const std::string& name, bool replace = false) {
  v1::UploadTreesRequest message;
  message.mutable_header()->set_name(name);
  message.mutable_header()->set_replace(replace);
  return message;
}

v1::UploadTreesRequest Chunk(int first_id, int count) {
  v1::UploadTreesRequest message;
  for (int i = 0; i < count; ++i) {
    v1::Tree* tree = message.mutable_chunk()->add_trees();
    tree->set_id(first_id + i);
    tree->set_x(i);
    tree->set_y(i);
  }
  return message;
}

v1::TrackRequest TrackHeader(const std::string& name) {
  v1::TrackRequest message;
  message.mutable_header()->set_name(name);
  return message;
}

TEST(ValidationTest, UploadHeaderBoundary) {
  const auto accept = [](const v1::SurveyBoundary& boundary) {
    v1::UploadTreesRequest header = Header("m");
    *header.mutable_header()->mutable_boundary() = boundary;
    UploadValidator validator(1000);
    validator.Accept(header);
  };
  const auto ring = [](v1::Ring* out, int vertices, double x0) {
    for (int i = 0; i < vertices; ++i) {
      v1::Vector2* v = out->add_vertices();
      v->set_x(x0 + std::cos(i));
      v->set_y(std::sin(i));
    }
  };
  v1::SurveyBoundary good;
  ring(good.add_polygons()->mutable_outer(), 4, 0);
  ring(good.mutable_polygons(0)->add_holes(), 3, 0);
  EXPECT_NO_THROW(accept(good));
  EXPECT_NO_THROW(accept(v1::SurveyBoundary()));  // removes the map's boundary

  v1::SurveyBoundary short_hole = good;
  short_hole.mutable_polygons(0)->mutable_holes(0)->mutable_vertices()->RemoveLast();
  EXPECT_THAT(
      ErrorOf<ValidationError>([&] { accept(short_hole); }),
      HasSubstr("header.boundary.polygons[0].holes[0] has 2 vertices; a ring needs at least 3"));
  v1::SurveyBoundary far = good;
  far.mutable_polygons(0)->mutable_outer()->mutable_vertices(1)->set_y(2e7);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { accept(far); }),
              HasSubstr("header.boundary.polygons[0].outer.vertices[1].y is"));
  v1::SurveyBoundary nan = good;
  nan.mutable_polygons(0)->mutable_outer()->mutable_vertices(2)->set_x(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { accept(nan); }),
              HasSubstr("header.boundary.polygons[0].outer.vertices[2].x is NaN"));
  v1::SurveyBoundary huge;
  ring(huge.add_polygons()->mutable_outer(), 100001, 0);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { accept(huge); }),
              HasSubstr("header.boundary has over 100000 vertices"));
}

TEST(ValidationTest, MapNames) {
  v1::GetMapRequest ok;
  ok.set_name("Plot_7.v2-b");
  EXPECT_NO_THROW(Validate(ok));
  v1::GetMapRequest empty;
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(empty); }), HasSubstr("name"));
  v1::DeleteMapRequest bad;
  bad.set_name("my map!");
  const std::string message = ErrorOf<ValidationError>([&] { Validate(bad); });
  EXPECT_THAT(message, HasSubstr("name \"my map!\""));
  EXPECT_THAT(message, HasSubstr("character 3"));
  v1::CreateMapRequest too_long;
  too_long.set_name(std::string(129, 'a'));
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(too_long); }), HasSubstr("128"));
  v1::ExportTreesRequest control;
  control.set_name(std::string("a\nb", 3));
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(control); }), HasSubstr("name \"a\\x0ab\""));
  EXPECT_EQ(FieldOf([&] { Validate(control); }), "name");
}

// "." and ".." are paths in a URL: the web page's /api/maps/../trees would name another route.
TEST(ValidationTest, DotAndDotDotAreNoMapNames) {
  for (const std::string name : {".", ".."}) {
    v1::CreateMapRequest create;
    create.set_name(name);
    const std::string message = ErrorOf<ValidationError>([&] { Validate(create); });
    EXPECT_THAT(message, HasSubstr("name \"" + name + "\""));
    EXPECT_THAT(message, HasSubstr("must not be \".\" or \"..\""));
  }
  for (const std::string name : {"...", ".a", "a..b", "v1.", "-"}) {
    v1::CreateMapRequest create;
    create.set_name(name);
    EXPECT_NO_THROW(Validate(create)) << name;
  }
}

TEST(ValidationTest, CreateMapLimitsDescriptionAndCrs) {
  v1::CreateMapRequest request;
  request.set_name("plot");
  request.set_description(std::string(kMaxDescriptionLength, 'd'));
  request.set_crs("EPSG:32612");
  EXPECT_NO_THROW(Validate(request));
  request.set_description(std::string(kMaxDescriptionLength + 1, 'd'));
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(request); }), HasSubstr("description"));
  request.clear_description();
  request.set_crs(std::string(kMaxCrsLength + 1, 'c'));
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(request); }), HasSubstr("crs"));
}

TEST(ValidationTest, TreeFields) {
  v1::Tree tree;
  tree.set_x(1);
  tree.set_y(2);
  EXPECT_NO_THROW(ValidateTree(tree, "trees[0]"));
  tree.set_z(-3);
  tree.set_dbh(0);
  tree.set_id(0);
  (*tree.mutable_attributes())["species"] = "pine";
  EXPECT_NO_THROW(ValidateTree(tree, "trees[0]"));

  v1::Tree nan_x = tree;
  nan_x.set_x(kNaN);
  EXPECT_EQ(ErrorOf<ValidationError>([&] { ValidateTree(nan_x, "trees[12]"); }),
            "trees[12].x is NaN; numbers must be finite");
  EXPECT_EQ(FieldOf([&] { ValidateTree(nan_x, "trees[12]"); }), "trees[12].x");
  v1::Tree inf_z = tree;
  inf_z.set_z(-kInf);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(inf_z, "trees[3]"); }),
              HasSubstr("trees[3].z is -inf"));
  v1::Tree negative_dbh = tree;
  negative_dbh.set_dbh(-0.2);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(negative_dbh, "trees[4]"); }),
              HasSubstr("trees[4].dbh is -0.2"));
  v1::Tree negative_id = tree;
  negative_id.set_id(-1);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(negative_id, "trees[5]"); }),
              HasSubstr("trees[5].id is -1"));
  v1::Tree empty_key = tree;
  (*empty_key.mutable_attributes())[""] = "x";
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(empty_key, "trees[6]"); }),
              HasSubstr("trees[6].attributes"));
}

// Null attributes (survey columns unknown for a tree): key rules as for attributes.
TEST(ValidationTest, NullAttributes) {
  v1::Tree tree;
  (*tree.mutable_attributes())["Spp"] = "41";
  tree.add_null_attributes("LI");
  EXPECT_NO_THROW(ValidateTree(tree, "trees[0]"));
  v1::Tree both = tree;
  both.add_null_attributes("Spp");
  EXPECT_EQ(ErrorOf<ValidationError>([&] { ValidateTree(both, "trees[1]"); }),
            "trees[1].null_attributes: \"Spp\" is also a key of attributes");
  v1::Tree empty = tree;
  empty.add_null_attributes("");
  EXPECT_EQ(ErrorOf<ValidationError>([&] { ValidateTree(empty, "trees[2]"); }),
            "trees[2].null_attributes has an empty key");
  v1::Tree many = tree;
  for (size_t i = 0; i < kMaxAttributes; ++i) many.add_null_attributes(std::to_string(i) + "c");
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(many, "trees[3]"); }),
              HasSubstr("trees[3].null_attributes: 66 attributes and null attributes exceed"));
}

// Finite but huge coordinates crashed the index build; a map frame is a local frame.
TEST(ValidationTest, CoordinatesMustLieInALocalFrame) {
  v1::Tree tree;
  tree.set_x(9.99e6);
  tree.set_y(-9.99e6);
  tree.set_z(9.9e4);
  EXPECT_NO_THROW(ValidateTree(tree, "trees[0]"));
  v1::Tree far_x = tree;
  far_x.set_x(1e308);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(far_x, "trees[3]"); }),
              HasSubstr("trees[3].x is 1e+308; coordinates must lie within +-10000000 m"));
  v1::Tree far_y = tree;
  far_y.set_y(-1e7);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(far_y, "trees[1]"); }),
              HasSubstr("trees[1].y is -10000000"));
  v1::Tree high = tree;
  high.set_z(1e5);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(high, "trees[2]"); }),
              HasSubstr("trees[2].z is 100000; coordinates must lie within +-100000 m"));

  v1::RelocalizeRequest query = Query(3);
  query.mutable_trees(1)->mutable_position()->set_y(2e7);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(query, 100); }),
              HasSubstr("trees[1].position.y is 20000000"));
  v1::RelocalizeRequest prior = Query(3);
  prior.mutable_prior()->set_radius_m(10);
  prior.mutable_prior()->set_x(-1e45);
  prior.mutable_prior()->set_y(0);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(prior, 100); }),
              HasSubstr("prior.x is -1e+45"));

  v1::ObserveRequest observe;
  observe.set_name("shared");
  observe.set_source("drone");
  v1::ObservationFrame* frame = observe.add_frames();
  frame->add_trees()->mutable_position()->set_z(3e5);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); }),
              HasSubstr("frames[0].trees[0].position.z is 300000"));
  frame->mutable_trees(0)->mutable_position()->set_z(1);
  frame->mutable_map_from_sensor()->mutable_translation()->set_y(1e45);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); }),
              HasSubstr("frames[0].map_from_sensor.translation.y is 1e+45"));

  v1::TrackRequest track;
  track.mutable_frame()->mutable_odometry()->mutable_translation()->set_x(5e7);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ReadTrackMessage(track, "plot", 100); }),
              HasSubstr("frame.odometry.translation.x is 50000000"));
}

// Observe writes trees as upload does: what upload refuses, Observe refuses, in the map frame.
TEST(ValidationTest, TheStatedSensorAndPoseSigmasAreCheckedByName) {
  const auto error_of = [](const std::function<void(v1::ObserveRequest&)>& set) {
    v1::ObserveRequest observe;
    observe.set_name("shared");
    observe.set_source("drone");
    observe.add_frames();
    set(observe);
    return ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); });
  };
  EXPECT_THAT(error_of([](v1::ObserveRequest& r) { r.set_detection_probability(1); }),
              HasSubstr("detection_probability is 1"));
  EXPECT_THAT(error_of([](v1::ObserveRequest& r) { r.set_sensor_range(-2); }),
              HasSubstr("sensor_range is -2"));
  EXPECT_THAT(error_of([](v1::ObserveRequest& r) { r.set_sensor_range(NAN); }),
              HasSubstr("sensor_range is nan"));
  EXPECT_THAT(error_of([](v1::ObserveRequest& r) { r.mutable_frames(0)->set_position_sigma(NAN); }),
              HasSubstr("frames[0].position_sigma is nan"));
  EXPECT_THAT(error_of([](v1::ObserveRequest& r) { r.mutable_frames(0)->set_yaw_sigma(7); }),
              HasSubstr("frames[0].yaw_sigma is 7"));
}

TEST(ValidationTest, ObservedTreesFollowTheUploadRulesInTheMapFrame) {
  v1::Tree huge_dbh;
  huge_dbh.set_dbh(1e308);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ValidateTree(huge_dbh, "trees[0]"); }),
              HasSubstr("trees[0].dbh is 1e+308"));

  v1::ObserveRequest observe;
  observe.set_name("shared");
  observe.set_source("drone");
  v1::ObservationFrame* frame = observe.add_frames();
  v1::DetectedTree* tree = frame->add_trees();
  tree->mutable_position()->set_z(6e4);
  frame->mutable_map_from_sensor()->mutable_translation()->set_z(6e4);
  frame->mutable_map_from_sensor()->mutable_rotation()->set_w(1);
  // Each within the bounds, the tree in the map frame at z = 120000 m is not.
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); }),
              HasSubstr("frames[0].trees[0] in the map frame: z is 120000"));
  EXPECT_EQ(FieldOf([&] { Validate(observe, ObserveLimits{}); }), "frames[0].trees[0]");
  // Rotated: a sensor tilted by 90 degrees about x turns the sensor's y into the map's z.
  frame->mutable_map_from_sensor()->mutable_rotation()->set_w(std::sqrt(0.5));
  frame->mutable_map_from_sensor()->mutable_rotation()->set_x(std::sqrt(0.5));
  frame->mutable_map_from_sensor()->mutable_translation()->set_z(0);
  tree->mutable_position()->set_z(0);
  tree->mutable_position()->set_y(9e4);
  EXPECT_NO_THROW(Validate(observe, ObserveLimits{}));
  frame->mutable_map_from_sensor()->mutable_translation()->set_z(2e4);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); }),
              HasSubstr("frames[0].trees[0] in the map frame: z is 110000"));
  frame->mutable_map_from_sensor()->mutable_translation()->set_z(0);
  tree->set_dbh(1e308);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(observe, ObserveLimits{}); }),
              HasSubstr("frames[0].trees[0].dbh is 1e+308"));
  tree->set_dbh(0.4);
  EXPECT_NO_THROW(Validate(observe, ObserveLimits{}));
}

// A gravity vector of any finite, non-zero length gives its direction, however long or short.
TEST(ValidationTest, GravityOfAnyFiniteNonZeroLengthIsNormalised) {
  const double kTolerance = 1e-12;
  for (const auto& [x, y, z] : {std::tuple{0.0, 0.0, -1e308},
                                {1e308, 1e308, 0.0},
                                {-1.7e308, 0.0, 1.7e308},
                                {0.0, 0.0, -1e-300},
                                {1e-300, -1e-300, 0.0},
                                {0.0, 4.9e-324, 0.0},
                                {3.0, 0.0, -4.0}}) {
    SCOPED_TRACE(std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z));
    v1::RelocalizeRequest request = Query(5);
    request.mutable_gravity()->set_x(x);
    request.mutable_gravity()->set_y(y);
    request.mutable_gravity()->set_z(z);
    EXPECT_NO_THROW(Validate(request, 100));
    const std::optional<Eigen::Vector3d> queried = FromProto(request).gravity;
    ASSERT_TRUE(queried.has_value());
    const Eigen::Vector3d gravity = *queried;
    EXPECT_NEAR(gravity.norm(), 1.0, kTolerance) << gravity.transpose();
    const double largest = std::max({std::abs(x), std::abs(y), std::abs(z)});
    const Eigen::Vector3d expected = Eigen::Vector3d(x / largest, y / largest, z / largest);
    EXPECT_TRUE(gravity.isApprox(expected.normalized(), kTolerance)) << gravity.transpose();

    v1::ObserveRequest observe;
    observe.set_name("shared");
    observe.set_source("drone");
    v1::ObservationFrame* frame = observe.add_frames();
    *frame->mutable_gravity() = request.gravity();
    *frame->add_trees() = request.trees(0);
    EXPECT_NO_THROW(Validate(observe, ObserveLimits{}));
    const std::optional<Eigen::Vector3d> observed = FromProto(observe).frames.at(0).gravity;
    ASSERT_TRUE(observed.has_value());
    EXPECT_TRUE(observed->isApprox(expected.normalized(), kTolerance)) << observed->transpose();
  }
  for (const double bad : {0.0, kNaN, kInf}) {
    v1::RelocalizeRequest request = Query(5);
    request.mutable_gravity()->set_x(bad);
    request.mutable_gravity()->set_y(bad == 0.0 ? 0.0 : 1.0);
    request.mutable_gravity()->set_z(0);
    EXPECT_THROW(Validate(request, 100), ValidationError) << bad;
  }
}

TEST(ValidationTest, RelocalizeTreeCountLimits) {
  EXPECT_NO_THROW(Validate(Query(3), 20000));
  // Fewer than 3 trees is a valid query, answered NOT_FOUND (TOO_FEW_TREES) by the relocalizer.
  EXPECT_NO_THROW(Validate(Query(2), 20000));
  EXPECT_NO_THROW(Validate(Query(0), 20000));
  EXPECT_EQ(ErrorOf<LimitError>([&] { Validate(Query(101), 100); }),
            "trees: 101 trees exceed the limit of 100 per query");
}

TEST(ValidationTest, RelocalizeDetectedTreeFields) {
  v1::RelocalizeRequest nan = Query(20);
  nan.mutable_trees(12)->mutable_position()->set_x(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(nan, 100); }),
              HasSubstr("trees[12].position.x is NaN"));
  v1::RelocalizeRequest missing = Query(5);
  missing.mutable_trees(4)->clear_position();
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(missing, 100); }),
              HasSubstr("trees[4].position is missing"));
  v1::RelocalizeRequest axis = Query(5);
  axis.mutable_trees(1)->mutable_axis();  // present but zero
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(axis, 100); }),
              HasSubstr("trees[1].axis is a zero vector"));
  v1::RelocalizeRequest score = Query(5);
  score.mutable_trees(2)->set_score(1.5);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(score, 100); }),
              HasSubstr("trees[2].score is 1.5"));
  v1::RelocalizeRequest dbh = Query(5);
  dbh.mutable_trees(0)->set_dbh(kInf);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(dbh, 100); }),
              HasSubstr("trees[0].dbh is +inf"));
}

TEST(ValidationTest, RelocalizePriorAndGravity) {
  v1::RelocalizeRequest request = Query(5);
  v1::PriorPose* prior = request.mutable_prior();
  prior->set_x(12.5);
  prior->set_y(-3);
  prior->set_radius_m(10);
  request.mutable_gravity()->set_z(-9.81);
  EXPECT_NO_THROW(Validate(request, 100));

  v1::RelocalizeRequest nan_y = request;
  nan_y.mutable_prior()->set_y(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(nan_y, 100); }), HasSubstr("prior.y is NaN"));
  v1::RelocalizeRequest no_x = request;
  no_x.mutable_prior()->clear_x();
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(no_x, 100); }),
              HasSubstr("prior.x is missing"));
  EXPECT_EQ(FieldOf([&] { Validate(no_x, 100); }), "prior.x");
  v1::RelocalizeRequest no_position = request;
  no_position.mutable_prior()->clear_x();
  no_position.mutable_prior()->clear_y();
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(no_position, 100); }),
              HasSubstr("prior.x is missing; a prior is the sensor's horizontal position"));
  v1::RelocalizeRequest radius = request;
  radius.mutable_prior()->set_radius_m(0);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(radius, 100); }),
              HasSubstr("prior.radius_m is 0; it must be > 0"));
  v1::RelocalizeRequest zero_gravity = request;
  zero_gravity.mutable_gravity()->set_z(0);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(zero_gravity, 100); }),
              HasSubstr("gravity is a zero vector"));
  v1::RelocalizeRequest nan_gravity = request;
  nan_gravity.mutable_gravity()->set_x(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(nan_gravity, 100); }),
              HasSubstr("gravity.x is NaN"));
}

TEST(ValidationTest, TrackStreamHeaderThenFrames) {
  v1::TrackRequest header = TrackHeader("plot");
  const TrackMessage first = ReadTrackMessage(header, "", 100);
  EXPECT_EQ(first.map, "plot");
  EXPECT_FALSE(first.frame);  // a header is not answered
  v1::TrackRequest frame;
  frame.mutable_frame()->set_frame_id(7);
  frame.mutable_frame()->add_trees()->mutable_position()->set_x(1);
  const TrackMessage next = ReadTrackMessage(frame, "plot", 100);
  ASSERT_TRUE(next.frame);
  EXPECT_EQ(next.frame->frame_id(), 7);
  EXPECT_EQ(next.frame->trees_size(), 1);

  v1::TrackRequest no_header;
  no_header.mutable_frame()->set_frame_id(1);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { ReadTrackMessage(no_header, "", 100); }),
              HasSubstr("header is missing: the first message of a Track stream names the map"));
  v1::TrackRequest second_header = TrackHeader("plot");
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(second_header, "plot", 100); }), "header");
  v1::TrackRequest bad_name = TrackHeader("a b");
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(bad_name, "", 100); }), "header.name");
  v1::TrackRequest nan;
  nan.mutable_frame()->add_trees()->mutable_position()->set_y(kNaN);
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(nan, "plot", 100); }), "frame.trees[0].position.y");
  v1::TrackRequest many;
  for (int i = 0; i < 11; ++i) many.mutable_frame()->add_trees()->mutable_position();
  EXPECT_EQ(ErrorOf<LimitError>([&] { ReadTrackMessage(many, "plot", 10); }),
            "frame.trees: 11 trees exceed the limit of 10 per frame");
}

TEST(ValidationTest, TrackHeaderMayNameASetOfMaps) {
  v1::TrackRequest header;
  header.mutable_header()->mutable_maps()->set_name_pattern("district-*");
  const TrackMessage first = ReadTrackMessage(header, "", 100);
  ASSERT_TRUE(first.maps);
  EXPECT_EQ(first.maps->name_pattern(), "district-*");
  EXPECT_TRUE(first.map.empty());
  v1::TrackRequest frame;
  frame.mutable_frame()->add_trees()->mutable_position();
  EXPECT_TRUE(ReadTrackMessage(frame, kSetSession, 100).frame);

  v1::TrackRequest both = header;
  both.mutable_header()->set_name("plot");
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(both, "", 100); }), "header.name");
  v1::TrackRequest empty;
  empty.mutable_header()->mutable_maps();
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(empty, "", 100); }), "header.maps");
  v1::TrackRequest twice;
  twice.mutable_header()->mutable_maps()->add_names("a");
  twice.mutable_header()->mutable_maps()->add_names("a");
  EXPECT_EQ(FieldOf([&] { ReadTrackMessage(twice, "", 100); }), "header.maps.names[1]");
  v1::TrackRequest many;
  for (const char* name : {"a", "b", "c"}) many.mutable_header()->mutable_maps()->add_names(name);
  EXPECT_EQ(ErrorOf<LimitError>([&] { ReadTrackMessage(many, "", 100, 2); }),
            "header.maps.names: 3 maps exceed the limit of 2 per question");
}

TEST(ValidationTest, RelocalizeOverASetOfMaps) {
  v1::RelocalizeRequest request;
  request.mutable_maps()->set_all_readable(true);
  EXPECT_NO_THROW(Validate(request, 100));
  request.set_name("plot");
  EXPECT_EQ(FieldOf([&] { Validate(request, 100); }), "name");
  request.clear_name();
  request.mutable_maps()->set_name_pattern(std::string(kMaxNamePatternLength + 1, '*'));
  EXPECT_EQ(FieldOf([&] { Validate(request, 100); }), "maps");  // two ways given
  request.mutable_maps()->set_all_readable(false);
  EXPECT_EQ(FieldOf([&] { Validate(request, 100); }), "maps.name_pattern");
}

TEST(ValidationTest, ExportBox) {
  v1::ExportTreesRequest request;
  request.set_name("plot");
  request.mutable_box()->set_max_x(10);
  request.mutable_box()->set_max_y(10);
  EXPECT_NO_THROW(Validate(request));
  request.mutable_box()->set_min_x(11);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(request); }), HasSubstr("box is empty"));
  request.mutable_box()->set_min_x(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { Validate(request); }), HasSubstr("box.min_x is NaN"));
}

TEST(ValidationTest, UploadStreamHappyPath) {
  UploadValidator validator(1000);
  v1::UploadTreesRequest header = Header("plot", /*replace=*/true);
  EXPECT_EQ(validator.Accept(header).size(), 0);
  for (int first_id : {0, 10, 20}) {
    v1::UploadTreesRequest chunk = Chunk(first_id, 10);
    EXPECT_EQ(validator.Accept(chunk).size(), 10);  // the trees, moved out of the message
  }
  v1::UploadTreesRequest no_ids;
  no_ids.mutable_chunk()->add_trees()->set_x(1);
  v1::UploadTreesRequest no_ids_again = no_ids;
  validator.Accept(no_ids);
  validator.Accept(no_ids_again);  // trees without ids never collide
  EXPECT_NO_THROW(validator.Finish());
  EXPECT_EQ(validator.header().name(), "plot");
  EXPECT_TRUE(validator.header().replace());
  EXPECT_EQ(validator.messages(), 6);
  EXPECT_EQ(validator.trees(), 32);
}

TEST(ValidationTest, UploadStreamErrors) {
  EXPECT_THAT(ErrorOf<ValidationError>([] { UploadValidator(10).Finish(); }),
              HasSubstr("header is missing: the upload stream was empty"));
  v1::UploadTreesRequest chunk = Chunk(0, 1);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { UploadValidator(10).Accept(chunk); }),
              HasSubstr("header is missing: the first message of an upload names the map"));
  v1::UploadTreesRequest bad_name = Header("a b");
  EXPECT_THAT(ErrorOf<ValidationError>([&] { UploadValidator(10).Accept(bad_name); }),
              HasSubstr("header.name \"a b\""));
  EXPECT_EQ(FieldOf([&] { UploadValidator(10).Accept(bad_name); }), "header.name");

  UploadValidator two_headers(100);
  v1::UploadTreesRequest header = Header("plot");
  two_headers.Accept(header);
  v1::UploadTreesRequest again = Header("plot");
  EXPECT_THAT(ErrorOf<ValidationError>([&] { two_headers.Accept(again); }),
              HasSubstr("header (upload message 1): only the first message of an upload is a "
                        "header"));

  // Ids unique across the stream are the store's check as it stages the trees (constant memory
  // here; tests/storage/staged_upload_test.cc, tests/server/service_test.cc).
  UploadValidator duplicate(100);
  duplicate.Accept(header);
  v1::UploadTreesRequest first_ten = Chunk(0, 10);
  duplicate.Accept(first_ten);
  v1::UploadTreesRequest overlapping = Chunk(5, 10);
  EXPECT_NO_THROW(duplicate.Accept(overlapping));

  UploadValidator nan(100);
  nan.Accept(header);
  v1::UploadTreesRequest good = Chunk(0, 10);
  nan.Accept(good);
  v1::UploadTreesRequest bad = Chunk(10, 5);
  bad.mutable_chunk()->mutable_trees(3)->set_y(kNaN);
  EXPECT_THAT(ErrorOf<ValidationError>([&] { nan.Accept(bad); }), HasSubstr("trees[13].y is NaN"));

  UploadValidator limit(15);
  limit.Accept(header);
  v1::UploadTreesRequest ten = Chunk(0, 10);
  limit.Accept(ten);
  v1::UploadTreesRequest six = Chunk(10, 6);
  EXPECT_THAT(ErrorOf<LimitError>([&] { limit.Accept(six); }),
              HasSubstr("exceeds the limit of 15 trees"));
}

}  // namespace
}  // namespace forestmap::server
