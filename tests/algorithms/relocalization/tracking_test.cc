// Tracking sessions (algorithms/relocalization/tracking.h) on the real Venman traversals: the
// second visit (Wild_V02) tracked frame by frame against the first visit's map (Wild_V01), and
// sessions that start lost, lose the track and turn faster than the prediction.
#include "algorithms/relocalization/tracking.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/algorithms/relocalization/venman_sequences.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

class Venman : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!std::filesystem::exists(kSequences + "Wild_V01/map.csv")) return;
    map_ = new std::vector<MapTree>(
        client::ToMapTrees(client::ReadMapTreesCsv(kSequences + "Wild_V01/map.csv")));
    index_ = new MapIndex(*map_);
    frames_ =
        new std::vector<client::Frame>(client::ReadFramesCsv(kSequences + "Wild_V02/trees.csv"));
    poses_ = new std::map<int64_t, Pose3>(client::ReadPosesCsv(kSequences + "Wild_V02/poses.csv"));
    stein_ = new std::vector<client::Frame>(
        client::ReadFramesCsv(kSequences + "Oxford_Stein/trees.csv"));
  }
  void SetUp() override {
    if (!map_) FORESTMAP_SKIP_WITHOUT_DATA() << "real sequences missing under " << kSequences;
  }

  Pose3 Truth(size_t i) const { return kV01FromV02 * poses_->at((*frames_)[i].frame); }
  TrackingFrame Frame(size_t i) const { return {{(*frames_)[i].trees, {}, {}}, std::nullopt}; }

  static std::vector<MapTree>* map_;
  static MapIndex* index_;
  static std::vector<client::Frame>* frames_;
  static std::map<int64_t, Pose3>* poses_;
  static std::vector<client::Frame>* stein_;
};
std::vector<MapTree>* Venman::map_ = nullptr;
MapIndex* Venman::index_ = nullptr;
std::vector<client::Frame>* Venman::frames_ = nullptr;
std::map<int64_t, Pose3>* Venman::poses_ = nullptr;
std::vector<client::Frame>* Venman::stein_ = nullptr;

TEST_F(Venman, TracksTheSecondVisitMostlyByLocalMatching) {
  Tracker tracker;
  RelocEvaluator evaluator(*map_);
  int local = 0;
  const size_t n = 400;
  for (size_t i = 0; i < n; ++i) {
    const TrackingStep step = tracker.Step(*index_, Frame(i));
    local += step.state == TrackState::kTracking;
    evaluator.Add(evaluator.Answerable((*frames_)[i].trees, Truth(i)), Truth(i), step.result, 0);
  }
  const RelocSummary s = evaluator.Summary();
  EXPECT_GE(s.recall, 0.995) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
  EXPECT_GE(local, 0.9 * n);
}

TEST_F(Venman, ASessionThatStartsLostRecoversWithinThreeFrames) {
  Tracker tracker;
  // Frames of another forest first: nothing fits, the session is lost and says so.
  for (int i = 0; i < 5; ++i) {
    const TrackingStep step = tracker.Step(*index_, {{(*stein_)[i * 10].trees, {}, {}}, {}});
    EXPECT_EQ(step.state, TrackState::kLost);
    EXPECT_EQ(step.frames_lost, i + 1);
    EXPECT_EQ(step.method, TrackMethod::kGlobal);
  }
  // Then the drone is in the map.
  int recovered_after = -1;
  for (size_t i = 0; i < 3 && recovered_after < 0; ++i) {
    const TrackingStep step = tracker.Step(*index_, Frame(100 + i));
    if (step.state == TrackState::kRecovered) {
      recovered_after = static_cast<int>(i);
      EXPECT_LE(ComparePoses(step.result.map_from_sensor, Truth(100 + i)).xy, 0.5);
    }
  }
  EXPECT_GE(recovered_after, 0) << "not recovered within 3 frames";
  // And the track goes on from there.
  int tracking = 0;
  for (size_t i = 100 + recovered_after + 1; i < 120; ++i) {
    const TrackingStep step = tracker.Step(*index_, Frame(i));
    ASSERT_NE(step.state, TrackState::kLost) << "frame " << i;
    EXPECT_LE(ComparePoses(step.result.map_from_sensor, Truth(i)).xy, 0.5) << "frame " << i;
    tracking += step.state == TrackState::kTracking;
  }
  EXPECT_GE(tracking, 15);
}

TEST_F(Venman, AnEmptyFrameAndAJumpAreRecovered) {
  Tracker tracker;
  for (size_t i = 200; i < 210; ++i) tracker.Step(*index_, Frame(i));
  // Nothing seen: lost, and the prediction carries on.
  const TrackingStep empty = tracker.Step(*index_, {{{}, {}, {}}, std::nullopt});
  EXPECT_EQ(empty.state, TrackState::kLost);
  EXPECT_EQ(empty.frames_lost, 1);
  // The drone reappears far away (hundreds of metres along the route): a search finds it.
  const size_t far = 900;
  ASSERT_GT((Truth(far).translation() - Truth(209).translation()).head<2>().norm(), 100.0);
  bool recovered = false;
  for (size_t i = far; i < far + 3 && !recovered; ++i) {
    const TrackingStep step = tracker.Step(*index_, Frame(i));
    recovered = step.state == TrackState::kRecovered;
    if (recovered) {
      EXPECT_LE(ComparePoses(step.result.map_from_sensor, Truth(i)).xy, 0.5);
    }
  }
  EXPECT_TRUE(recovered);
}

TEST_F(Venman, OdometryKeepsEveryFrameLocal) {
  Tracker tracker;
  int local = 0, correct = 0;
  const size_t begin = 500, end = 700;
  for (size_t i = begin; i < end; ++i) {
    TrackingFrame frame = Frame(i);
    if (i > begin) frame.odometry = Truth(i - 1).inverse() * Truth(i);
    const TrackingStep step = tracker.Step(*index_, frame);
    local += step.state == TrackState::kTracking;
    correct += step.result.status == RelocalizeStatus::kLocalized &&
               ComparePoses(step.result.map_from_sensor, Truth(i)).xy <= 0.5;
  }
  EXPECT_GE(local, static_cast<int>(end - begin) - 5);
  EXPECT_GE(correct, static_cast<int>(end - begin) - 1);
}

// A simulated drone that turns 60 degrees between frames without odometry: the prediction keeps
// the old heading, and local matching finds the turn from the bearing alignment.
TEST(Tracking, AFastTurnWithoutOdometryStaysLocal) {
  StemMapStatistics stats;
  stats.density = 0.05;
  ForestOptions forest;
  forest.width = forest.height = 200;
  forest.seed = 3;
  const std::vector<MapTree> map = GenerateForest(stats, forest);
  const MapIndex index(map);
  ViewSimulator simulator(map);
  ViewOptions view;
  view.range = 20;
  Tracker tracker;
  int local = 0, correct = 0;
  const int n = 30;
  for (int i = 0; i < n; ++i) {
    view.seed = 100 + i;
    const Eigen::Vector2d xy(60 + 2.0 * i, 100);
    const SimulatedView v = simulator.Simulate(xy, i * M_PI / 3, view);
    const TrackingStep step = tracker.Step(index, {{v.trees, {}, {}}, std::nullopt});
    local += step.state == TrackState::kTracking;
    const PoseError error = ComparePoses(step.result.map_from_sensor, v.map_from_sensor);
    correct +=
        step.result.status == RelocalizeStatus::kLocalized && error.xy <= 0.5 && error.yaw <= 5;
  }
  EXPECT_EQ(correct, n);
  EXPECT_GE(local, n - 3);
}

TEST(Tracking, RejectsInvalidOptions) {
  TrackingOptions options;
  options.max_correction = 0;
  EXPECT_THROW(Tracker{options}, std::invalid_argument);
  options = {};
  options.local_min_matched = 1.5;
  EXPECT_THROW(Tracker{options}, std::invalid_argument);
  options = {};
  options.relocalizer.min_inliers = 1;
  EXPECT_THROW(Tracker{options}, std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
