// The relocalizer on real forest data: a few hundred real frames of the Venman and Stein am
// Rhein traversals against their surveyed maps, with the ground-truth poses of
// ../shared/data/sequences, and frames of one forest against the map of another.
#include <gtest/gtest.h>

#include <filesystem>
#include <optional>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/relocalizer.h"
#include "client/io/tree_csv.h"
#include "tests/algorithms/relocalization/venman_sequences.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

std::vector<MapTree> ReadMap(const std::string& name) {
  return client::ToMapTrees(client::ReadMapTreesCsv(kSequences + name + "/map.csv"));
}

// Relocalizes every `step`-th frame of `sequence` against `map`; with `prior_offset`, the
// query carries a prior at the truth moved by that offset (radius 10 m).
RelocSummary RunSequence(const std::vector<MapTree>& map, const std::string& sequence, int step,
                         const Pose3& map_from_world,
                         const std::optional<Eigen::Vector3d>& prior_offset = std::nullopt) {
  const MapIndex index(map);
  RelocEvaluator evaluator(map);
  const auto poses = client::ReadPosesCsv(kSequences + sequence + "/poses.csv");
  const auto frames = client::ReadFramesCsv(kSequences + sequence + "/trees.csv");
  for (size_t i = 0; i < frames.size(); i += step) {
    const Pose3 truth = map_from_world * poses.at(frames[i].frame);
    RelocalizeQuery query;
    query.trees = frames[i].trees;
    if (prior_offset) {
      query.prior = PriorPose{truth, 10.0};
      query.prior->map_from_sensor.translation() += *prior_offset;
    }
    const RelocalizeResult result = Relocalize(index, query);
    evaluator.Add(evaluator.Answerable(query.trees, truth), truth, result, 0);
  }
  return evaluator.Summary();
}

RelocSummary RunSequence(const std::string& map_name, const std::string& sequence, int step,
                         const Pose3& map_from_world) {
  return RunSequence(ReadMap(map_name), sequence, step, map_from_world);
}

class RealSequences : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kSequences + "Wild_V01/map.csv")) {
      FORESTMAP_SKIP_WITHOUT_DATA() << "real sequences missing under " << kSequences;
    }
  }
};

TEST_F(RealSequences, SecondVisitToVenmanLocalizesAgainstTheFirstVisitsMap) {
  const RelocSummary s = RunSequence("Wild_V01", "Wild_V02", 5, kV01FromV02);  // 275 frames
  EXPECT_GE(s.answerable, 250);
  EXPECT_GE(s.recall, 0.99) << s.correct << " of " << s.answerable;
  // The two sessions' ground truths drift 0.1-0.2 m apart along the route: strict answers
  // (0.2 m) and the median error are bounded by that, not by the relocalizer.
  EXPECT_GE(s.strict_recall, 0.94);
  EXPECT_EQ(s.wrong, 0);
  EXPECT_LT(s.error_xy_p50, 0.15);  // m
}

TEST_F(RealSequences, SteeplyTiltedSteinFramesLocalizeInTheirMap) {
  const RelocSummary s = RunSequence("Oxford_Stein", "Oxford_Stein", 5, Pose3::Identity());
  EXPECT_GE(s.answerable, 200);
  EXPECT_GE(s.recall, 0.98) << s.correct << " of " << s.answerable;
  EXPECT_GE(s.strict_recall, 0.96);
  EXPECT_EQ(s.wrong, 0);
}

TEST_F(RealSequences, APriorThreeMetresOffStillFindsThePose) {
  const RelocSummary s =
      RunSequence(ReadMap("Wild_V01"), "Wild_V02", 5, kV01FromV02, Eigen::Vector3d(2.1, -2.1, 0));
  EXPECT_GE(s.answerable, 250);
  EXPECT_GE(s.recall, 0.99) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST_F(RealSequences, APriorAtTheWrongPlaceGivesNoAnswerRatherThanAGuess) {
  const RelocSummary s =
      RunSequence(ReadMap("Wild_V01"), "Wild_V02", 10, kV01FromV02, Eigen::Vector3d(40, 0, 0));
  EXPECT_EQ(s.localized, 0) << s.wrong << " wrong";
}

TEST_F(RealSequences, ATwoDimensionalMapWithoutDbhWorksInThreeDof) {
  std::vector<MapTree> map = ReadMap("Wild_V01");
  for (MapTree& tree : map) tree.position.z() = tree.dbh = kUnknown;  // a field survey: x, y
  ASSERT_FALSE(MapIndex(map).has_z());
  const RelocSummary s = RunSequence(map, "Wild_V02", 5, kV01FromV02);
  EXPECT_GE(s.recall, 0.99) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST_F(RealSequences, FramesOfAnotherForestAreNeverLocalized) {
  const RelocSummary s = RunSequence("Oxford_Stein", "Wild_V02", 5, Pose3::Identity());
  EXPECT_EQ(s.not_found, s.frames);
}

}  // namespace
}  // namespace forestmap::algorithms
