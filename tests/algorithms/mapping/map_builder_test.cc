// Mapping without poses (algorithms/mapping/map_builder.h) and its pose graph (pose_graph.h): a
// simulated loop through a generated forest and a stretch of the real Wild_V01 traversal.

#include "algorithms/mapping/map_builder.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "algorithms/evaluation/map_evaluation.h"
#include "algorithms/mapping/pose_graph.h"
#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

TEST(PoseGraph, LoopEdgeRemovesAccumulatedDrift) {
  // 100 poses on a 50 m circle; odometry with a heading bias and a 1% short step.
  std::vector<Pose4> truth, drifted;
  std::vector<PoseGraphEdge> edges;
  for (int i = 0; i < 100; ++i) {
    const double a = 2 * M_PI * i / 100;
    Pose4 p;
    p.translation = Eigen::Vector3d(50 * std::cos(a), 50 * std::sin(a), 0.01 * i);
    p.yaw = WrapAngle(a + M_PI / 2);
    truth.push_back(p);
  }
  drifted.push_back(truth[0]);
  for (int i = 1; i < 100; ++i) {
    PoseGraphEdge edge;
    edge.from = i - 1;
    edge.to = i;
    edge.measurement = Between(truth[i - 1], truth[i]);
    edge.measurement.yaw += 0.002;
    edge.measurement.translation.x() *= 0.99;
    edges.push_back(edge);
    drifted.push_back(Compose(drifted.back(), edge.measurement));
  }
  PoseGraphEdge loop;
  loop.from = 0;
  loop.to = 99;
  loop.measurement = Between(truth[0], truth[99]);
  loop.robust = true;
  edges.push_back(loop);
  double before = 0, after = 0;
  const PoseGraphResult result = OptimizePoseGraph(drifted, edges);
  for (int i = 0; i < 100; ++i) {
    before = std::max(before, (drifted[i].translation - truth[i].translation).norm());
    after = std::max(after, (result.poses[i].translation - truth[i].translation).norm());
  }
  EXPECT_GT(before, 5.0);
  EXPECT_LT(after, 0.15 * before);
  EXPECT_LT(result.final_cost, result.initial_cost);
  PoseGraphEdge bad;
  bad.to = 100;
  EXPECT_THROW(OptimizePoseGraph(drifted, {bad}), std::invalid_argument);
}

struct SimulatedRun {
  std::vector<MapTree> forest;
  std::vector<BuilderFrame> frames;
  std::vector<Pose3> truth;
};

// A drone walking a closed rectangle (every 2 m, heading along the path, tilted sensor) through
// a generated forest, twice round so that the second lap revisits the first.
SimulatedRun SimulateLoop() {
  SimulatedRun run;
  StemMapStatistics stats;
  stats.density = 0.03;
  stats.min_spacing = 1.0;
  ForestOptions forest;
  forest.width = 140;
  forest.height = 120;
  forest.seed = 11;
  run.forest = GenerateForest(stats, forest);
  ViewSimulator simulator(run.forest);
  ViewOptions view;
  view.range = 30;
  view.max_tilt = 0.25;
  const Eigen::Vector2d corners[] = {{30, 30}, {110, 30}, {110, 90}, {30, 90}};
  for (int lap = 0; lap < 2; ++lap) {
    for (int side = 0; side < 4; ++side) {
      const Eigen::Vector2d a = corners[side], b = corners[(side + 1) % 4];
      const double yaw = std::atan2(b.y() - a.y(), b.x() - a.x());
      const int steps = static_cast<int>((b - a).norm() / 2.0);
      for (int s = 0; s < steps; ++s) {
        view.seed = static_cast<unsigned>(run.frames.size() + 1);
        const SimulatedView v = simulator.Simulate(a + (b - a) * s / steps, yaw, view);
        BuilderFrame frame;
        frame.frame_id = static_cast<int64_t>(run.frames.size());
        frame.trees = v.trees;
        run.frames.push_back(frame);
        run.truth.push_back(v.map_from_sensor);
      }
    }
  }
  return run;
}

TEST(MapBuilder, SimulatedLoopHasSmallTrajectoryErrorAndNoDuplicateTrees) {
  const SimulatedRun run = SimulateLoop();
  MapBuilder builder;
  int fixed = 0;
  for (const BuilderFrame& frame : run.frames) {
    fixed += builder.AddFrame(frame).fix != FrameFix::kDeadReckoned;
  }
  builder.Finish();
  EXPECT_EQ(fixed, static_cast<int>(run.frames.size()));
  const TrajectoryError ate = CompareTrajectories(builder.Poses(), run.truth, Alignment::kPlanar);
  EXPECT_LT(ate.ate_rmse, 0.3);
  EXPECT_LT(ate.ate_max, 0.8);
  std::vector<MapTree> aligned = builder.ConfirmedTrees();
  for (MapTree& tree : aligned) tree.position = ate.ToTruth(tree.position);
  const TreeMapComparison c = CompareTreeMaps(aligned, run.forest, {0.3, 0.3});
  EXPECT_GT(c.found, static_cast<int>(run.forest.size() / 2));
  EXPECT_LT(c.distance_p50, 0.1);
  EXPECT_LE(c.duplicates, c.built_trees / 200);  // the second lap does not map trees twice
}

TEST(MapBuilder, RealWildV01StretchWithoutPoses) {
  const auto dir = std::filesystem::path(FORESTMAP_SHARED_DATA) / "sequences" / "Wild_V01";
  if (!std::filesystem::exists(dir / "trees.csv")) {
    FORESTMAP_SKIP_WITHOUT_DATA() << "real sequences missing under " << dir;
  }
  const auto frames = client::ReadFramesCsv((dir / "trees.csv").string());
  const auto poses = client::ReadPosesCsv((dir / "poses.csv").string());
  MapBuilder builder;
  std::vector<Pose3> truth;
  for (size_t i = 0; i < 300 && i < frames.size(); ++i) {
    BuilderFrame frame;
    frame.frame_id = frames[i].frame;
    frame.trees = frames[i].trees;
    builder.AddFrame(frame);
    truth.push_back(poses.at(frames[i].frame));
  }
  const TrajectoryError ate = CompareTrajectories(builder.Poses(), truth, Alignment::kPlanar);
  EXPECT_LT(ate.ate_rmse, 0.3);  // 600 m of handheld traversal
  EXPECT_GT(builder.map().ConfirmedTrees().size(), 2000u);
}

TEST(MapBuilder, FirstFrameDefinesTheMapFrameAndOptionsAreChecked) {
  MapBuilderOptions options;
  options.icp_gates.clear();
  EXPECT_THROW(MapBuilder{options}, std::invalid_argument);
  MapBuilder builder;
  BuilderFrame empty;
  EXPECT_EQ(builder.AddFrame(empty).fix, FrameFix::kFirst);
  EXPECT_TRUE(builder.Poses()[0].isApprox(Pose3::Identity()));
  EXPECT_EQ(builder.AddFrame(empty).fix, FrameFix::kDeadReckoned);  // nothing to match: no crash
}

}  // namespace
}  // namespace forestmap::algorithms
