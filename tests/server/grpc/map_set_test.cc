// Relocalize over a set of maps, end to end: plot maps cut from one generated forest served by a
// real in-process gRPC server (127.0.0.1 port 0, in-memory SQLite, a token store), a view in one
// plot found with its map's name over the set, foreign views not found, the set by names,
// pattern or every readable map, narrowed by a prior and by the caller's token, and its limits.

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "algorithms/simulation/view_simulator.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/ops/auth.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/algorithms/relocalization/generated_forest.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using algorithms::MapTree;
using ::testing::HasSubstr;
using ::testing::UnorderedElementsAre;

constexpr auto kMapSetDeadline = std::chrono::seconds(60);  // turns a hang into a failure
constexpr double kMapSetPoseTolerance = 0.3;                // m, horizontal error of a found pose
constexpr double kPlotWidth = 150;                          // m: x in [0, 150) and [150, 300)

// One generated forest, 300 m x 300 m, and another that no map holds.
const std::vector<MapTree>& District() {
  static const std::vector<MapTree> forest = algorithms::testing_util::Forest(7, 300);
  return forest;
}
const std::vector<MapTree>& Foreign() {
  static const std::vector<MapTree> forest = algorithms::testing_util::Forest(8, 300);
  return forest;
}

std::vector<v1::Tree> Cut(const std::vector<MapTree>& forest, double min_x, double max_x,
                          double shift_x = 0) {
  std::vector<v1::Tree> trees;
  for (const MapTree& tree : forest) {
    if (tree.position.x() < min_x || tree.position.x() >= max_x) continue;
    v1::Tree& out = trees.emplace_back();
    out.set_id(tree.id);
    out.set_x(tree.position.x() + shift_x);
    out.set_y(tree.position.y());
    if (std::isfinite(tree.position.z())) out.set_z(tree.position.z());
    if (std::isfinite(tree.dbh)) out.set_dbh(tree.dbh);
  }
  return trees;
}

// A simulated view of `forest` from (x, y), as a request; its true pose in `truth`.
v1::RelocalizeRequest ViewAt(const std::vector<MapTree>& forest, double x, double y, double yaw,
                             unsigned seed, algorithms::Pose3* truth = nullptr) {
  algorithms::ViewOptions options;
  options.seed = seed;
  const algorithms::SimulatedView view =
      algorithms::ViewSimulator(forest).Simulate({x, y}, yaw, options);
  if (truth != nullptr) *truth = view.map_from_sensor;
  v1::RelocalizeRequest request;
  for (const algorithms::DetectedTree& tree : view.trees) {
    v1::DetectedTree* out = request.add_trees();
    out->mutable_position()->set_x(tree.position.x());
    out->mutable_position()->set_y(tree.position.y());
    out->mutable_position()->set_z(tree.position.z());
    if (std::isfinite(tree.dbh)) out->set_dbh(tree.dbh);
  }
  return request;
}

double HorizontalError(const v1::RelocalizeResponse& answer, const algorithms::Pose3& truth) {
  return std::hypot(answer.map_from_sensor().translation().x() - truth.translation().x(),
                    answer.map_from_sensor().translation().y() - truth.translation().y());
}

class MapSetTest : public ::testing::Test {
 protected:
  explicit MapSetTest(int max_query_maps = kDefaultMaxQueryMaps)
      : tokens_(":memory:"),
        authorizer_(&tokens_),
        service_(store_, Options(&authorizer_, max_query_maps)),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}

  static ServiceOptions Options(const Authorizer* authorizer, int max_query_maps) {
    ServiceOptions options;
    options.authorizer = authorizer;
    options.max_query_maps = max_query_maps;
    return options;
  }

  // The district's two plots, a map of another forest and an empty map (made while the server
  // is open: no token exists yet).
  void SetUp() override {
    Create("district-a", Cut(District(), 0, kPlotWidth));
    Create("district-b", Cut(District(), kPlotWidth, 2 * kPlotWidth));
    Create("elsewhere", Cut(Foreign(), 0, kPlotWidth, 5000));
    Create("district-empty", {});
  }

  void Create(const std::string& name, const std::vector<v1::Tree>& trees,
              const std::string& crs = "") {
    auto context = test::CallContext(kMapSetDeadline);
    v1::UploadTreesResponse response;
    auto writer = stub_->UploadTrees(context.get(), &response);
    v1::UploadTreesRequest header = test::UploadHeader(name, false, true);
    header.mutable_header()->set_crs(crs);
    bool open = writer->Write(header);
    for (size_t next = 0; open && next < trees.size();) {
      v1::UploadTreesRequest message;
      for (size_t end = std::min(trees.size(), next + 1000); next < end; ++next) {
        *message.mutable_chunk()->add_trees() = trees[next];
      }
      open = writer->Write(message);
    }
    writer->WritesDone();
    const grpc::Status status = writer->Finish();
    ASSERT_TRUE(status.ok()) << name << ": " << status.error_message();
  }

  grpc::Status Relocalize(const v1::RelocalizeRequest& request, v1::RelocalizeResponse* answer,
                          const std::string& token = "") {
    auto context = test::CallContext(kMapSetDeadline);
    if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
    return stub_->Relocalize(context.get(), request, answer);
  }

  storage::SqliteMapStore store_{":memory:"};
  storage::TokenStore tokens_;
  Authorizer authorizer_;
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
};

TEST_F(MapSetTest, ViewInOnePlotIsFoundWithItsMapNameByNamesPatternOrAllMaps) {
  const std::vector<std::function<void(v1::MapSet&)>> sets = {
      [](v1::MapSet& set) {
        for (const char* name : {"elsewhere", "district-b", "district-a"}) set.add_names(name);
      },
      [](v1::MapSet& set) { set.set_name_pattern("district-*"); },
      [](v1::MapSet& set) { set.set_all_readable(true); },
  };
  for (size_t k = 0; k < sets.size(); ++k) {
    for (const auto& [x, map] : {std::pair{75.0, "district-a"}, std::pair{225.0, "district-b"}}) {
      algorithms::Pose3 truth;
      v1::RelocalizeRequest request = ViewAt(District(), x, 140, 0.4 * k, 10 + k, &truth);
      sets[k](*request.mutable_maps());
      v1::RelocalizeResponse answer;
      const grpc::Status status = Relocalize(request, &answer);
      ASSERT_TRUE(status.ok()) << status.error_message();
      ASSERT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED)
          << "set " << k << ", " << map << ": " << answer.detail();
      EXPECT_EQ(answer.map_name(), map) << "set " << k;
      EXPECT_LT(HorizontalError(answer, truth), kMapSetPoseTolerance) << "set " << k;
      EXPECT_EQ(answer.map_version(), 2);  // created and written by one upload
      EXPECT_TRUE(answer.rival_map_name().empty());
    }
  }
}

TEST_F(MapSetTest, OneNamedMapAnswersWithItsName) {
  v1::RelocalizeRequest request = ViewAt(District(), 70, 60, 1.0, 3);
  request.set_name("district-a");
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  EXPECT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.detail();
  EXPECT_EQ(answer.map_name(), "district-a");
}

TEST_F(MapSetTest, ViewsOfAForestInNoMapAreNotFound) {
  for (unsigned k = 0; k < 6; ++k) {
    v1::RelocalizeRequest request = ViewAt(Foreign(), 170 + 20 * k, 40 + 40 * k, 0.5 * k, 30 + k);
    request.mutable_maps()->set_all_readable(true);
    v1::RelocalizeResponse answer;
    ASSERT_TRUE(Relocalize(request, &answer).ok());
    EXPECT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_NOT_FOUND)
        << "view " << k << " answered in " << answer.map_name() << ": " << answer.detail();
  }
}

TEST_F(MapSetTest, APlotCopiedIntoAnotherMapMakesTheViewAmbiguousAcrossMaps) {
  Create("twin-a", Cut(District(), 0, kPlotWidth, 1000));
  v1::RelocalizeRequest request = ViewAt(District(), 80, 200, 2.0, 5);
  request.mutable_maps()->add_names("district-a");
  request.mutable_maps()->add_names("twin-a");
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  EXPECT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_AMBIGUOUS) << answer.detail();
  EXPECT_EQ(answer.reason(), v1::RelocalizeResponse::REASON_AMBIGUOUS_RIVAL);
  EXPECT_THAT((std::vector<std::string>{answer.map_name(), answer.rival_map_name()}),
              UnorderedElementsAre("district-a", "twin-a"));
  EXPECT_FALSE(answer.has_map_from_sensor());
  EXPECT_THAT(answer.detail(), HasSubstr("disagree"));
}

TEST_F(MapSetTest, OverlappingMapsOfOneFrameAgreeOnThePose) {
  Create("overlap-ab", Cut(District(), 100, 200));
  algorithms::Pose3 truth;
  v1::RelocalizeRequest request = ViewAt(District(), 125, 150, 0.2, 6, &truth);
  request.mutable_maps()->set_all_readable(true);
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  ASSERT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.detail();
  EXPECT_THAT(answer.map_name(), ::testing::AnyOf("district-a", "overlap-ab"));
  EXPECT_LT(HorizontalError(answer, truth), kMapSetPoseTolerance);
}

// Plot maps in one CRS are one forest: a view on their boundary is found in the index of their
// union, the answer naming one of them and each match its own map.
TEST_F(MapSetTest, MapsOfOneCrsFindAViewOnTheirBoundaryWithEachMatchsMap) {
  Create("utm-a", Cut(District(), 0, kPlotWidth), "EPSG:32633");
  Create("utm-b", Cut(District(), kPlotWidth, 2 * kPlotWidth), "EPSG:32633");
  int across = 0;
  for (unsigned k = 0; k < 4; ++k) {
    algorithms::Pose3 truth;
    v1::RelocalizeRequest request =
        ViewAt(District(), kPlotWidth, 60 + 50 * k, 0.7 * k, 40 + k, &truth);
    request.mutable_maps()->set_name_pattern("utm-*");
    v1::RelocalizeResponse answer;
    const grpc::Status status = Relocalize(request, &answer);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.detail();
    EXPECT_LT(HorizontalError(answer, truth), kMapSetPoseTolerance);
    EXPECT_THAT(answer.map_name(), ::testing::AnyOf("utm-a", "utm-b"));
    EXPECT_TRUE(answer.has_geodetic());
    std::set<std::string> maps;
    for (const v1::TreeMatch& match : answer.matches()) {
      EXPECT_NE(match.map_name(), answer.map_name());  // named only when another map's
      maps.insert(match.map_name().empty() ? answer.map_name() : match.map_name());
    }
    across += maps.size() == 2;
  }
  EXPECT_GE(across, 3);
}

TEST_F(MapSetTest, APriorLeavesOutTheMapsItCannotMeetWithoutBuildingTheirIndexes) {
  v1::RelocalizeRequest request = ViewAt(District(), 60, 100, 0.0, 7);
  request.mutable_maps()->set_all_readable(true);
  request.mutable_prior()->set_x(-4000);  // far from every map
  request.mutable_prior()->set_y(0);
  request.mutable_prior()->set_radius_m(50);
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  EXPECT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_NOT_FOUND);
  EXPECT_EQ(answer.reason(), v1::RelocalizeResponse::REASON_OUTSIDE_PRIOR);
  EXPECT_TRUE(answer.map_name().empty());
  EXPECT_EQ(service_.index_cache().stats().builds, 0);

  request.mutable_prior()->set_x(60);  // plot a only: district-b begins 90 m away
  request.mutable_prior()->set_y(100);
  request.mutable_prior()->set_radius_m(10);
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  EXPECT_EQ(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.detail();
  EXPECT_EQ(answer.map_name(), "district-a");
  EXPECT_EQ(service_.index_cache().stats().builds, 1);
}

TEST_F(MapSetTest, ATokenSearchesOnlyTheMapsItMayRead) {
  const std::string plot_a = tokens_.Create("district-a", storage::Role::kRead).secret;
  v1::RelocalizeRequest request = ViewAt(District(), 225, 150, 0.3, 8);  // in plot b
  request.mutable_maps()->set_name_pattern("district-*");
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(Relocalize(request, &answer, plot_a).ok());
  EXPECT_NE(answer.status(), v1::RelocalizeResponse::STATUS_LOCALIZED) << answer.map_name();
  EXPECT_NE(answer.map_name(), "district-b");

  request.clear_maps();
  request.mutable_maps()->add_names("district-a");
  request.mutable_maps()->add_names("district-b");
  const grpc::Status denied = Relocalize(request, &answer, plot_a);
  EXPECT_EQ(denied.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_THAT(denied.error_message(), HasSubstr("district-b"));

  request.clear_maps();
  request.mutable_maps()->set_name_pattern("else*");
  const grpc::Status none = Relocalize(request, &answer, plot_a);
  EXPECT_EQ(none.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(none.error_message(), HasSubstr("else*"));
}

TEST_F(MapSetTest, BadSetsAreRefusedNamingTheField) {
  const v1::RelocalizeRequest view = ViewAt(District(), 75, 140, 0, 9);
  const std::vector<std::pair<std::function<void(v1::RelocalizeRequest&)>, grpc::StatusCode>>
      cases = {
          {[](auto& r) { r.mutable_maps(); }, grpc::StatusCode::INVALID_ARGUMENT},
          {[](auto& r) {
             r.set_name("district-a");
             r.mutable_maps()->set_all_readable(true);
           },
           grpc::StatusCode::INVALID_ARGUMENT},
          {[](auto& r) {
             r.mutable_maps()->set_all_readable(true);
             r.mutable_maps()->set_name_pattern("district-*");
           },
           grpc::StatusCode::INVALID_ARGUMENT},
          {[](auto& r) {
             r.mutable_maps()->add_names("district-a");
             r.mutable_maps()->add_names("district-a");
           },
           grpc::StatusCode::INVALID_ARGUMENT},
          {[](auto& r) { r.mutable_maps()->add_names("bad name!"); },
           grpc::StatusCode::INVALID_ARGUMENT},
          {[](auto& r) { r.mutable_maps()->add_names("no-such-map"); },
           grpc::StatusCode::NOT_FOUND},
          {[](auto& r) { r.mutable_maps()->set_name_pattern("nothing-*"); },
           grpc::StatusCode::NOT_FOUND},
      };
  for (size_t k = 0; k < cases.size(); ++k) {
    v1::RelocalizeRequest request = view;
    cases[k].first(request);
    v1::RelocalizeResponse answer;
    EXPECT_EQ(Relocalize(request, &answer).error_code(), cases[k].second) << "case " << k;
  }
}

// A flight along y = 150 from plot a (x < 150) into plot b, 2 m a frame with odometry, tracked
// in one session: the answers, and each frame's true pose.
struct Flight {
  std::vector<v1::TrackResponse> answers;
  std::vector<algorithms::Pose3> truths;
  grpc::Status status;
};
constexpr double kFlightStart = 110, kFlightStep = 2;
constexpr int kFlightFrames = 46;  // to x = 200

Flight Fly(v1::ForestMap::Stub& stub, const v1::TrackHeader& header) {
  Flight flight;
  auto context = test::CallContext(kMapSetDeadline);
  auto stream = stub.Track(context.get());
  v1::TrackRequest first;
  *first.mutable_header() = header;
  bool open = stream->Write(first);
  for (int k = 0; open && k < kFlightFrames; ++k) {
    algorithms::Pose3 truth;
    const v1::RelocalizeRequest view =
        ViewAt(District(), kFlightStart + kFlightStep * k, 150, 0.0, 100 + k, &truth);
    v1::TrackRequest message;
    v1::TrackFrame* frame = message.mutable_frame();
    *frame->mutable_trees() = view.trees();
    frame->set_frame_id(k);
    if (k > 0) {
      frame->mutable_odometry()->mutable_translation()->set_x(kFlightStep);
      frame->mutable_odometry()->mutable_rotation()->set_w(1);
    }
    v1::TrackResponse answer;
    open = stream->Write(message) && stream->Read(&answer);
    if (!open) break;
    flight.answers.push_back(answer);
    flight.truths.push_back(truth);
  }
  stream->WritesDone();
  flight.status = stream->Finish();
  return flight;
}

TEST_F(MapSetTest, ATrackOverTheDistrictCrossesFromOnePlotMapIntoTheNext) {
  v1::TrackHeader header;
  header.mutable_maps()->set_name_pattern("district-*");
  const Flight flight = Fly(*stub_, header);
  ASSERT_TRUE(flight.status.ok()) << flight.status.error_message();
  ASSERT_EQ(flight.answers.size(), static_cast<size_t>(kFlightFrames));
  int with_pose = 0;
  for (size_t k = 0; k < flight.answers.size(); ++k) {
    const v1::TrackResponse& answer = flight.answers[k];
    const double x = flight.truths[k].translation().x();
    if (answer.state() == v1::TrackResponse::STATE_LOST) continue;
    ++with_pose;
    EXPECT_LT(HorizontalError(answer.result(), flight.truths[k]), kMapSetPoseTolerance)
        << "x " << x;
    if (x < 140) {
      EXPECT_EQ(answer.result().map_name(), "district-a") << "x " << x;
    } else if (x > 165) {
      EXPECT_EQ(answer.result().map_name(), "district-b") << "x " << x;
    }
  }
  EXPECT_GE(with_pose, kFlightFrames - 2);
  EXPECT_EQ(flight.answers.back().result().map_name(), "district-b");

  // Tracked in plot a alone, the same flight loses its pose in plot b.
  header.Clear();
  header.set_name("district-a");
  const Flight alone = Fly(*stub_, header);
  ASSERT_TRUE(alone.status.ok()) << alone.status.error_message();
  EXPECT_EQ(alone.answers.back().state(), v1::TrackResponse::STATE_LOST);
  EXPECT_EQ(alone.answers.front().result().map_name(), "district-a");

  header.mutable_maps()->set_all_readable(true);  // a name beside a set
  const Flight both = Fly(*stub_, header);
  EXPECT_EQ(both.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(both.status.error_message(), HasSubstr("header.name"));
}

class MapSetLimitTest : public MapSetTest {
 protected:
  MapSetLimitTest() : MapSetTest(2) {}
};

TEST_F(MapSetLimitTest, MoreMapsThanTheLimitAreRefusedUnlessAPriorLeavesFewer) {
  v1::RelocalizeRequest request = ViewAt(District(), 60, 100, 0.0, 11);
  request.mutable_maps()->set_all_readable(true);  // three maps with trees
  v1::RelocalizeResponse answer;
  const grpc::Status over = Relocalize(request, &answer);
  EXPECT_EQ(over.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(over.error_message(), HasSubstr("limit of 2"));

  request.mutable_prior()->set_x(60);
  request.mutable_prior()->set_y(100);
  request.mutable_prior()->set_radius_m(20);
  ASSERT_TRUE(Relocalize(request, &answer).ok());
  EXPECT_EQ(answer.map_name(), "district-a");

  request.clear_maps();
  for (const char* name : {"district-a", "district-b", "elsewhere"}) {
    request.mutable_maps()->add_names(name);
  }
  EXPECT_EQ(Relocalize(request, &answer).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(service_.index_cache().stats().builds, 1);  // only the prior's question built any
}

}  // namespace
}  // namespace forestmap::server
