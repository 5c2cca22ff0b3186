// The writes of a shared map without gRPC (server/app/shared_map.h), on an in-memory store and a
// surveyed plot whose tree positions and sensor poses are the truth: frames with a pose merge as
// one new version (one without trees too: it saw none), frames without one are relocalized or
// skipped with the reason, a stale base is ABORTED before anything is done, a request id answers
// its repeat from the store, and a source's observations can be taken out again.

#include "server/app/shared_map.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

constexpr int kSurveyTrees = 40;
constexpr double kPlotSize = 30;         // m, square plot
constexpr double kPoseTolerance = 0.05;  // m, a relocalized sensor position vs the truth
const algorithms::Pose3 kSensor = algorithms::PoseFromXyzYaw(14, 16, 1.5, 0.4);

class SharedMapTest : public ::testing::Test {
 protected:
  SharedMapTest() {
    std::mt19937 random(7);
    std::uniform_real_distribution<double> metres(0, kPlotSize), dbh(0.15, 0.5);
    std::vector<storage::TreeRecord> survey;
    while (static_cast<int>(survey.size()) < kSurveyTrees) {
      const Eigen::Vector3d p(metres(random), metres(random), 0);
      bool apart = true;
      for (const storage::TreeRecord& t : survey)
        apart = apart && (Eigen::Vector2d(t.x, t.y) - p.head<2>()).norm() > 2.5;
      if (!apart) continue;
      storage::TreeRecord tree;
      tree.x = p.x();
      tree.y = p.y();
      tree.z = 0;
      tree.dbh = dbh(random);
      survey.push_back(tree);
    }
    store_.CreateMap("plot", "", "");
    store_.WriteTrees("plot", survey, storage::WriteMode::kAppend);  // version 2
    store_.CreateMap("empty", "", "");
  }

  // A frame from `source` at kSensor seeing the first `count` survey trees (sensor frame).
  ObserveFrame Frame(int64_t frame_id, int count, bool with_pose) {
    ObserveFrame frame;
    frame.observations.source = "drone-1";
    frame.observations.frame_id = frame_id;
    const std::vector<storage::TreeRecord> trees = store_.ReadMapVersion("plot", 2).trees;
    for (int i = 0; i < count; ++i) {
      algorithms::DetectedTree seen;
      seen.position = kSensor.inverse() * Eigen::Vector3d(trees[i].x, trees[i].y, 0.0);
      seen.dbh = *trees[i].dbh;
      frame.observations.trees.push_back(seen);
    }
    frame.has_pose = with_pose;
    if (with_pose) frame.observations.map_from_sensor = kSensor;
    return frame;
  }
  ObserveCall Call(std::vector<ObserveFrame> frames, const std::string& map = "plot") {
    ObserveCall call;
    call.write.rpc = "Observe";
    call.map_name = map;
    call.source = "drone-1";
    call.frames = std::move(frames);
    return call;
  }
  Written<ObserveOutcome> Run(const ObserveCall& call, bool cancelled = false) {
    return ApplyObserve(store_, index_cache_, call, options_, Encode,
                        [cancelled] { return cancelled; });
  }
  // The stored answer: the map version and each frame's fate.
  static std::string Encode(const ObserveOutcome& outcome) {
    std::string text = "v" + std::to_string(outcome.map.version);
    for (const FrameOutcome& frame : outcome.frames) text += frame.merged ? " merged" : " skipped";
    return text;
  }

  storage::SqliteMapStore store_{":memory:"};
  MapIndexCache index_cache_{store_};
  SharedMapOptions options_;
};

TEST_F(SharedMapTest, FramesWithAPoseMergeAsOneNewVersion) {
  const Written<ObserveOutcome> written =
      Run(Call({Frame(1, 20, true), Frame(2, 0, true), Frame(3, 25, true)}));
  ASSERT_FALSE(written.replayed.has_value());
  const ObserveOutcome& outcome = written.outcome;
  ASSERT_EQ(outcome.frames.size(), 3u);
  EXPECT_TRUE(outcome.frames[0].merged);
  EXPECT_FALSE(outcome.frames[0].relocalized);
  EXPECT_EQ(outcome.frames[0].counts.associated, 20);  // every detection met its survey tree
  EXPECT_EQ(outcome.frames[0].counts.added, 0);
  // A pose without trees saw nothing: evidence of absence only.
  EXPECT_TRUE(outcome.frames[1].merged);
  EXPECT_EQ(outcome.frames[1].counts.associated + outcome.frames[1].counts.added, 0);
  EXPECT_EQ(outcome.frames[2].counts.associated, 25);
  EXPECT_EQ(outcome.map.version, 3);
  EXPECT_EQ(store_.GetMap("plot").version, 3);
  EXPECT_EQ(store_.GetMap("plot").tree_count, kSurveyTrees);
}

TEST_F(SharedMapTest, AFrameWithoutAPoseIsRelocalizedOrSkippedWithTheReason) {
  const Written<ObserveOutcome> written = Run(Call({Frame(1, 2, false), Frame(2, 30, false)}));
  const ObserveOutcome& outcome = written.outcome;
  ASSERT_EQ(outcome.frames.size(), 2u);
  EXPECT_FALSE(outcome.frames[0].merged);
  EXPECT_EQ(outcome.frames[0].detail, "no pose given and fewer than 3 trees to relocalize with");
  ASSERT_TRUE(outcome.frames[1].merged) << outcome.frames[1].detail;
  EXPECT_TRUE(outcome.frames[1].relocalized);
  EXPECT_LT((outcome.frames[1].map_from_sensor.translation() - kSensor.translation()).norm(),
            kPoseTolerance);
  EXPECT_EQ(outcome.map.version, 3);

  const Written<ObserveOutcome> nothing = Run(Call({Frame(1, 10, false)}, "empty"));
  ASSERT_EQ(nothing.outcome.frames.size(), 1u);
  EXPECT_THAT(nothing.outcome.frames[0].detail,
              HasSubstr("no pose given and the map cannot relocalize: "));
  EXPECT_EQ(nothing.outcome.map.version, 1);  // nothing merged, nothing written
  EXPECT_EQ(store_.GetMap("empty").version, 1);
}

TEST_F(SharedMapTest, AStaleBaseIsAbortedBeforeAnything) {
  ObserveCall call = Call({Frame(1, 20, true)});
  call.base_version = 1;  // the map is at 2
  try {
    Run(call);
    ADD_FAILURE() << "a stale base merged";
  } catch (const ServiceError& e) {
    EXPECT_EQ(e.code(), ErrorCode::kAborted);
    EXPECT_THAT(e.what(), HasSubstr("rejected as stale"));
  }
  EXPECT_EQ(store_.GetMap("plot").version, 2);
  call.base_version = 2;
  EXPECT_EQ(Run(call).outcome.map.version, 3);
}

TEST_F(SharedMapTest, ARepeatedRequestIdIsAnsweredFromTheStore) {
  ObserveCall call = Call({Frame(1, 20, true), Frame(2, 2, false)});
  call.write.request_id = "observe-1";
  const Written<ObserveOutcome> first = Run(call);
  ASSERT_FALSE(first.replayed.has_value());
  EXPECT_EQ(Encode(first.outcome), "v3 merged skipped");
  const Written<ObserveOutcome> again = Run(call);
  ASSERT_TRUE(again.replayed.has_value());
  EXPECT_EQ(*again.replayed, "v3 merged skipped");
  EXPECT_EQ(store_.GetMap("plot").version, 3);
}

TEST_F(SharedMapTest, ACancelledCallWritesNothing) {
  const Written<ObserveOutcome> written = Run(Call({Frame(1, 20, true)}), /*cancelled=*/true);
  EXPECT_TRUE(written.outcome.cancelled);
  EXPECT_EQ(store_.GetMap("plot").version, 2);
}

TEST_F(SharedMapTest, RemoveSourceTakesItsObservationsOutAsANewVersion) {
  Run(Call({Frame(1, 20, true), Frame(3, 25, true)}));
  const auto encode = [](const SourceRemovalOutcome& o) {
    return std::to_string(o.observations_removed);
  };
  const Written<SourceRemovalOutcome> removed = ApplyRemoveSource(
      store_, WriteCall{"remove-1", "RemoveSource"}, "plot", "drone-1", options_.merge, encode);
  ASSERT_FALSE(removed.replayed.has_value());
  EXPECT_EQ(removed.outcome.observations_removed, 45);
  EXPECT_EQ(removed.outcome.trees_removed, 0);  // survey trees stay
  EXPECT_EQ(removed.outcome.map.version, 4);
  EXPECT_EQ(ApplyRemoveSource(store_, WriteCall{"remove-1", "RemoveSource"}, "plot", "drone-1",
                              options_.merge, encode)
                .replayed,
            "45");
  try {
    ApplyRemoveSource(store_, WriteCall{"", "RemoveSource"}, "plot", "drone-1", options_.merge,
                      encode);
    ADD_FAILURE() << "no error";
  } catch (const ServiceError& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNotFound);
  }
}

}  // namespace
}  // namespace forestmap::server
