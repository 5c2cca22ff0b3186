// The relocalizer on real forest data: a few hundred real frames of the Venman and Stein am
// Rhein traversals against their surveyed maps, with the ground-truth poses of
// ../shared/data/sequences, and frames of one forest against the map of another.
#include <filesystem>

#include <gtest/gtest.h>

#include "algorithms/reloc_evaluation.h"
#include "algorithms/relocalizer.h"
#include "client/tree_csv.h"

namespace forestmap::algorithms {
namespace {

const std::string kSequences = std::string(FORESTMAP_SHARED_DATA) + "/sequences/";

// Wild_V02's ground truth is offset from Wild_V01's (../shared/data/README.md):
// map_V01_from_map_V02 = translation (0.051, 0.102, -0.039) m, yaw -0.014 deg.
const Pose3 kV01FromV02 = PoseFromXyzYaw(0.051, 0.102, -0.039, -0.014 * M_PI / 180.0);

RelocSummary RunSequence(const std::string& map_name, const std::string& sequence, int step,
                         const Pose3& map_from_world) {
  const std::vector<MapTree> map = client::ToMapTrees(client::ReadMapTreesCsv(kSequences + map_name + "/map.csv"));
  const MapIndex index(map);
  RelocEvaluator evaluator(map);
  const auto poses = client::ReadPosesCsv(kSequences + sequence + "/poses.csv");
  const auto frames = client::ReadFramesCsv(kSequences + sequence + "/trees.csv");
  for (size_t i = 0; i < frames.size(); i += step) {
    const Pose3 truth = map_from_world * poses.at(frames[i].frame);
    RelocalizeQuery query;
    query.trees = frames[i].trees;
    const RelocalizeResult result = Relocalize(index, query);
    evaluator.Add(evaluator.Answerable(query.trees, truth), truth, result, 0);
  }
  return evaluator.Summary();
}

class RealSequences : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kSequences + "Wild_V01/map.csv")) {
      GTEST_SKIP() << "real sequences missing under " << kSequences;
    }
  }
};

TEST_F(RealSequences, SecondVisitToVenmanLocalizesAgainstTheFirstVisitsMap) {
  const RelocSummary s = RunSequence("Wild_V01", "Wild_V02", 5, kV01FromV02);  // 275 frames
  EXPECT_GE(s.answerable, 250);
  EXPECT_GE(s.recall, 0.97) << s.correct << " of " << s.answerable;
  EXPECT_GE(s.strict_recall, 0.90);
  EXPECT_EQ(s.wrong, 0);
  EXPECT_LT(s.error_xy_p50, 0.15);  // m
}

TEST_F(RealSequences, SteeplyTiltedSteinFramesLocalizeInTheirMap) {
  const RelocSummary s = RunSequence("Oxford_Stein", "Oxford_Stein", 5, Pose3::Identity());
  EXPECT_GE(s.answerable, 200);
  EXPECT_GE(s.recall, 0.90) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST_F(RealSequences, FramesOfAnotherForestAreNeverLocalized) {
  const RelocSummary s = RunSequence("Oxford_Stein", "Wild_V02", 10, Pose3::Identity());
  EXPECT_EQ(s.localized, 0);
  EXPECT_EQ(s.not_found + s.ambiguous, s.frames);
}

}  // namespace
}  // namespace forestmap::algorithms
