// Map merging (algorithms/merging/map_merge.h, merged_map.h): association, DBH awareness,
// promotion, removal, order robustness on a simulated forest and the survey merge on real frames.

#include "algorithms/merging/map_merge.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <random>
#include <span>
#include <tuple>

#include "algorithms/core/kdtree.h"
#include "algorithms/evaluation/map_evaluation.h"
#include "algorithms/merging/merged_map.h"
#include "algorithms/merging/observation_components.h"
#include "algorithms/simulation/forest_generator.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

constexpr double kExact = 1e-9;  // m, "the same number" after identical arithmetic

DetectedTree Detection(double x, double y, double dbh, double score = 0.9) {
  DetectedTree tree;
  tree.position = Eigen::Vector3d(x, y, 0);
  tree.dbh = dbh;
  tree.axis = Eigen::Vector3d::UnitZ();
  tree.score = score;
  return tree;
}

// A tree built from `n` observations at `xy` seen from sensors 3 m apart (confirmed).
TreeEstimate KnownTree(int64_t id, double x, double y, double dbh, int n = 4) {
  std::vector<TreeObservation> rows;
  for (int i = 0; i < n; ++i) {
    TreeObservation row;
    row.tree_id = id;
    row.position = Eigen::Vector3d(x, y, 0);
    row.dbh = dbh;
    row.weight_xy = 400;
    row.weight_dbh = 1000;
    row.sensor_position = Eigen::Vector3d(x + 3.0 * i, y + 5, 1.5);
    rows.push_back(row);
  }
  return EstimateFromObservations(id, rows);
}

FrameObservations FrameAt(const Eigen::Vector2d& sensor, std::vector<DetectedTree> trees,
                          int64_t frame_id = 1, const std::string& source = "drone") {
  FrameObservations frame;
  frame.source = source;
  frame.frame_id = frame_id;
  frame.map_from_sensor = PoseFromXyzYaw(sensor.x(), sensor.y(), 0, 0);
  for (DetectedTree& tree : trees) tree.position.head<2>() -= sensor;
  frame.trees = std::move(trees);
  return frame;
}

TEST(MapMerge, AssociationIsOneToOnePerFrameAndGated) {
  const std::vector<TreeEstimate> map = {KnownTree(10, 0, 0, 0.3), KnownTree(11, 1, 0, 0.3)};
  const MergeResult result =
      MergeFrame(map, FrameAt({0, -5}, {Detection(0.05, 0, 0.3), Detection(0.12, 0.05, 0.3),
                                        Detection(0.75, 0, 0.3), Detection(5, 5, 0.3)}));
  ASSERT_EQ(result.assignment.size(), 4u);
  EXPECT_EQ(result.assignment[0], 10);  // the closer of two detections takes tree 10
  EXPECT_LT(result.assignment[1], 0);   // the other may not take it too: a new candidate
  EXPECT_EQ(result.assignment[2], 11);  // 0.25 m from tree 11, 0.75 m (beyond the gate) from 10
  EXPECT_LT(result.assignment[3], 0);   // far from everything
  EXPECT_EQ(result.associated, 2);
  EXPECT_EQ(result.created, 2);
  ASSERT_EQ(result.new_trees.size(), 2u);
  EXPECT_EQ(result.new_trees[0].status, TreeStatus::kCandidate);
  EXPECT_EQ(result.observations.size(), 4u);
}

TEST(MapMerge, DbhDecidesBetweenNeighboursAndRejectsADistinctStem) {
  const std::vector<TreeEstimate> map = {KnownTree(1, 0, 0, 0.10), KnownTree(2, 0.45, 0, 0.50)};
  // 0.15 m from the thin tree, 0.30 m from the thick one, with the thick tree's DBH.
  MergeResult result = MergeFrame(map, FrameAt({0, -6}, {Detection(0.15, 0, 0.50)}));
  EXPECT_EQ(result.assignment[0], 2);
  // A 0.4 m stem 0.35 m from a lone 0.1 m tree: the stems do not overlap and the DBHs disagree.
  const std::vector<TreeEstimate> lone = {KnownTree(1, 0, 0, 0.10)};
  result = MergeFrame(lone, FrameAt({0, -6}, {Detection(0.35, 0, 0.40)}));
  EXPECT_LT(result.assignment[0], 0);
  // The same detection without a DBH joins the tree: position alone is within the gate.
  result = MergeFrame(lone, FrameAt({0, -6}, {Detection(0.35, 0, kUnknown)}));
  EXPECT_EQ(result.assignment[0], 1);
  // A wild DBH fit right on the stem joins that tree despite its DBH, which is averaged with its
  // weight (a stored row is never rewritten: the map must not depend on the order of rows).
  result = MergeFrame(lone, FrameAt({0, -6}, {Detection(0.05, 0, 0.60)}));
  ASSERT_EQ(result.assignment[0], 1);
  ASSERT_EQ(result.updated_trees.size(), 1u);
  const double w_tree = lone[0].dbh_stats.weight, w_row = result.observations[0].weight_dbh;
  EXPECT_NEAR(result.updated_trees[0].dbh, (w_tree * 0.10 + w_row * 0.60) / (w_tree + w_row),
              kExact);
  EXPECT_EQ(result.updated_trees[0].observations, 5);
}

TEST(MapMerge, PromotionNeedsDistinctViewsNotRepeatedFrames) {
  MergedMap map;
  for (int frame = 0; frame < 6; ++frame) {  // a hovering drone: one spot, six frames
    map.Merge(FrameAt({0, -5}, {Detection(0, 0, 0.3)}, frame));
  }
  ASSERT_EQ(map.size(), 1u);
  EXPECT_EQ(map.Trees()[0].observations, 6);
  EXPECT_EQ(map.Trees()[0].distinct_views, 1);
  EXPECT_EQ(map.Trees()[0].status, TreeStatus::kCandidate);
  map.Merge(FrameAt({2, -5}, {Detection(0, 0, 0.3)}, 10));
  EXPECT_EQ(map.Trees()[0].status, TreeStatus::kCandidate);
  const MergeResult third = map.Merge(FrameAt({4, -5}, {Detection(0, 0, 0.3)}, 11));
  EXPECT_EQ(map.Trees()[0].status, TreeStatus::kConfirmed);
  EXPECT_EQ(map.Trees()[0].distinct_views, 3);
  ASSERT_EQ(third.promoted_ids.size(), 1u);
  EXPECT_EQ(third.promoted_ids[0], map.Trees()[0].id);
}

TEST(MapMerge, SurveyedTreeIsAConfirmedStrongPrior) {
  MergedMap map;
  map.AddSurvey({MapTree{7, Eigen::Vector3d(10, 10, 0), 0.4}});
  ASSERT_EQ(map.ConfirmedTrees().size(), 1u);
  EXPECT_TRUE(map.Trees()[0].surveyed);
  map.Merge(FrameAt({10, 0}, {Detection(10.2, 10, 0.3)}));  // 10 m range: sigma ~6 cm
  const TreeEstimate tree = map.Trees()[0];
  EXPECT_EQ(tree.id, 7);
  EXPECT_EQ(tree.observations, 2);
  EXPECT_GT(tree.position.x(), 10.0);
  EXPECT_LT(tree.position.x(), 10.1);  // the survey (5 cm sigma) outweighs one detection
}

// Views along a lawnmower path over a simulated forest, with truth poses.
std::vector<FrameObservations> SimulatedFrames(const std::vector<MapTree>& forest, int rows,
                                               unsigned seed) {
  ViewSimulator simulator(forest);
  ViewOptions view;
  view.range = 15;
  view.max_tilt = 0.2;
  std::vector<FrameObservations> frames;
  for (int row = 0; row < rows; ++row) {
    for (double s = 10; s <= 70; s += 2) {
      const double x = row % 2 == 0 ? s : 80 - s;
      view.seed = seed + static_cast<unsigned>(frames.size());
      const SimulatedView v = simulator.Simulate({x, 12.0 + 14.0 * row}, row % 2 ? M_PI : 0, view);
      FrameObservations frame;
      frame.source = "sim";
      frame.frame_id = static_cast<int64_t>(frames.size());
      frame.map_from_sensor = v.map_from_sensor;
      frame.trees = v.trees;
      frames.push_back(std::move(frame));
    }
  }
  return frames;
}

std::vector<MapTree> TestForest() {
  StemMapStatistics stats;
  stats.density = 0.04;
  stats.min_spacing = 1.0;
  ForestOptions forest;
  forest.width = 80;
  forest.height = 70;
  forest.seed = 3;
  return GenerateForest(stats, forest);
}

TEST(MapMerge, RemovingOneSourceRestoresThePreviousEstimate) {
  const std::vector<FrameObservations> frames = SimulatedFrames(TestForest(), 2, 5);
  MergedMap map;
  for (size_t i = 0; i < frames.size() / 2; ++i) map.Merge(frames[i]);
  const std::vector<TreeEstimate> before = map.Trees();
  for (size_t i = frames.size() / 2; i < frames.size(); ++i) {
    FrameObservations bad = frames[i];
    bad.source = "bad-drone";
    map.Merge(bad);
  }
  ASSERT_GT(map.size(), before.size());
  map.RemoveSource("bad-drone");
  const std::vector<TreeEstimate> after = map.Trees();
  ASSERT_EQ(after.size(), before.size());
  for (size_t i = 0; i < before.size(); ++i) {
    EXPECT_EQ(after[i].id, before[i].id);
    EXPECT_NEAR((after[i].position - before[i].position).head<2>().norm(), 0, kExact);
    EXPECT_EQ(after[i].observations, before[i].observations);
    EXPECT_EQ(after[i].status, before[i].status);
    if (IsKnown(before[i].dbh)) {
      EXPECT_NEAR(after[i].dbh, before[i].dbh, kExact);
    }
  }
}

TEST(MapMerge, EstimateFromObservationsEqualsIncrementalMerge) {
  const std::vector<FrameObservations> frames = SimulatedFrames(TestForest(), 1, 9);
  MergedMap map;
  for (const FrameObservations& frame : frames) map.Merge(frame);
  std::map<int64_t, std::vector<TreeObservation>> rows;
  for (const TreeObservation& row : map.observations()) rows[row.tree_id].push_back(row);
  for (const TreeEstimate& tree : map.Trees()) {
    const TreeEstimate again = EstimateFromObservations(tree.id, rows[tree.id]);
    EXPECT_NEAR((again.position - tree.position).head<2>().norm(), 0, kExact);
    EXPECT_NEAR(again.position_sigma, tree.position_sigma, kExact);
    EXPECT_EQ(again.distinct_views, tree.distinct_views);
    EXPECT_EQ(again.status, tree.status);
  }
}

// The rows of `frames` as ObserveFrame makes them, all of one placeholder tree (id 0): a
// rebuild forgets the association anyway.
std::vector<TreeObservation> RowsOf(const std::vector<FrameObservations>& frames) {
  std::vector<TreeObservation> rows;
  for (const FrameObservations& frame : frames) {
    const std::vector<TreeObservation> more = ObserveFrame(frame);
    rows.insert(rows.end(), more.begin(), more.end());
  }
  return rows;
}

// What a rebuild decides, without the id labels: every tree's state, sorted.
using TreeState = std::tuple<double, double, double, int, int, TreeStatus>;
std::vector<TreeState> States(const std::vector<TreeEstimate>& trees) {
  std::vector<TreeState> states;
  for (const TreeEstimate& t : trees) {
    states.emplace_back(t.position.x(), t.position.y(), IsKnown(t.dbh) ? t.dbh : -1, t.observations,
                        t.distinct_views, t.status);
  }
  std::sort(states.begin(), states.end());
  return states;
}

// The concurrency bar in miniature: four "drones" upload quarters of the frames interleaved
// (as parallel uploads arrive), against one sequential upload; after consolidation both give the
// same confirmed trees within 1 cm.
TEST(MapMerge, InterleavedQuartersGiveTheSameConfirmedTreesAsSequential) {
  constexpr double kSameTree = 0.01;  // m
  const std::vector<MapTree> forest = TestForest();
  const std::vector<FrameObservations> frames = SimulatedFrames(forest, 4, 21);
  MergedMap sequential;
  for (const FrameObservations& frame : frames) sequential.Merge(frame);
  sequential.Consolidate();
  MergedMap parallel;
  const size_t quarter = (frames.size() + 3) / 4;
  for (size_t k = 0; k < quarter; ++k) {
    for (size_t q = 0; q < 4; ++q) {
      if (q * quarter + k < frames.size()) parallel.Merge(frames[q * quarter + k]);
    }
  }
  parallel.Consolidate();
  const std::vector<MapTree> a = sequential.ConfirmedMapTrees();
  const std::vector<MapTree> b = parallel.ConfirmedMapTrees();
  ASSERT_GT(a.size(), forest.size() / 2);
  const TreeMapComparison same = CompareTreeMaps(b, a, {kSameTree, 0.3});
  EXPECT_EQ(b.size(), a.size());
  EXPECT_EQ(same.found, static_cast<int>(a.size()));
  const TreeMapComparison truth = CompareTreeMaps(a, forest, {0.2, 0.3});
  EXPECT_EQ(truth.duplicates, 0);
  EXPECT_LT(truth.distance_p50, 0.05);
  // Rebuilt from their observations (what the server holds), the two maps are one.
  sequential.Rebuild();
  parallel.Rebuild();
  EXPECT_EQ(States(parallel.Trees()), States(sequential.Trees()));
}

// The map is a pure function of the set of observations: the same rows in any order, or each
// connected component rebuilt on its own, give the same trees to the last bit.
TEST(MapMerge, RebuildIsAPureFunctionOfTheSetOfObservations) {
  const std::vector<TreeObservation> rows = RowsOf(SimulatedFrames(TestForest(), 4, 21));
  TreeEstimate placeholder;
  const std::span<const TreeEstimate> trees(&placeholder, 1);
  const ConsolidateResult whole = RebuildTrees(trees, rows, 1);
  ASSERT_GT(whole.trees.size(), 100u);
  EXPECT_EQ(whole.observations.size(), rows.size());

  std::vector<TreeObservation> shuffled = rows;
  std::mt19937 rng(3);
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  EXPECT_EQ(States(RebuildTrees(trees, shuffled, 1).trees), States(whole.trees));

  const std::vector<int> component = ObservationComponents(rows);
  const int count = *std::max_element(component.begin(), component.end()) + 1;
  ASSERT_GT(count, 100);
  std::vector<std::vector<TreeObservation>> parts(count);
  for (size_t r = 0; r < rows.size(); ++r) parts[component[r]].push_back(rows[r]);
  std::vector<TreeEstimate> by_part;
  for (const std::vector<TreeObservation>& part : parts) {
    const ConsolidateResult one = RebuildTrees(trees, part, 1);
    by_part.insert(by_part.end(), one.trees.begin(), one.trees.end());
  }
  EXPECT_EQ(States(by_part), States(whole.trees));
}

// A summary row stands for the rows it folds (the same tree from either) and fixes its tree in a
// rebuild: the tree keeps its id, 0 too, and the rows since join it around the summary.
TEST(MapMerge, ASummaryRowStandsForItsRowsAndKeepsItsTree) {
  std::vector<TreeObservation> folded;
  for (int k = 0; k < 40; ++k) {
    TreeObservation row;
    row.source = "drone";
    row.frame_id = k;
    row.detection_index = 0;
    row.position = Eigen::Vector3d(0.01 * (k % 7), -0.01 * (k % 5), 0.1 * (k % 3));
    row.dbh = 0.3 + 0.01 * (k % 4);
    row.weight_xy = 400;
    row.weight_dbh = 1000;
    row.sensor_position = Eigen::Vector3d(k, -5, 0);
    folded.push_back(row);
  }
  const TreeObservation summary = SummaryObservation(0, folded);
  ASSERT_TRUE(summary.summary && summary.defines_tree());
  const TreeEstimate from_rows = EstimateFromObservations(0, folded);
  const TreeEstimate from_summary = EstimateFromObservations(0, {&summary, 1});
  EXPECT_NEAR((from_summary.position - from_rows.position).norm(), 0, 1e-12);
  EXPECT_NEAR(from_summary.dbh, from_rows.dbh, 1e-12);
  EXPECT_NEAR(from_summary.position_sigma, from_rows.position_sigma, 1e-12);
  EXPECT_NEAR(from_summary.dbh_sigma, from_rows.dbh_sigma, 1e-12);
  EXPECT_EQ(from_summary.observations, 40);
  EXPECT_EQ(from_summary.distinct_views, from_rows.distinct_views);
  EXPECT_EQ(from_summary.status, TreeStatus::kConfirmed);

  // Five later rows, stored under another tree (7), near the summary.
  std::vector<TreeObservation> rows{summary};
  std::vector<TreeObservation> all = folded;
  for (int k = 0; k < 5; ++k) {
    TreeObservation row = folded[k];
    row.tree_id = 7;
    row.frame_id = 100 + k;
    row.position.x() += 0.05;
    rows.push_back(row);
    all.push_back(row);
  }
  TreeEstimate zero, seven;
  zero.id = 0, seven.id = 7;
  const std::vector<TreeEstimate> trees{seven, zero};
  const ConsolidateResult rebuilt = RebuildTrees(trees, rows, 100);
  ASSERT_EQ(rebuilt.trees.size(), 1u);
  EXPECT_EQ(rebuilt.trees[0].id, 0);
  EXPECT_TRUE(rebuilt.trees[0].summarized);
  EXPECT_EQ(rebuilt.trees[0].observations, 45);
  EXPECT_EQ(rebuilt.removed_ids, std::vector<int64_t>{7});
  for (const TreeObservation& row : rebuilt.observations) EXPECT_EQ(row.tree_id, 0);
  std::stable_sort(all.begin(), all.end(),
                   [](const auto& a, const auto& b) { return a.frame_id < b.frame_id; });
  const TreeEstimate whole = EstimateFromObservations(0, all);
  EXPECT_NEAR((rebuilt.trees[0].position - whole.position).norm(), 0, 1e-12);
}

std::filesystem::path Sequence(const std::string& name) {
  return std::filesystem::path(FORESTMAP_SHARED_DATA) / "sequences" / name;
}

// The survey-merge bar on a real subset: 400 consecutive Wild_V01 frames (430-829, a stretch
// the route does not revisit, so the reference's averages come from these frames too) with
// their true poses, scored on the reference trees within 10 m of that path.
TEST(MapMergeRealData, WildV01SubsetMatchesTheReferenceMap) {
  const auto dir = Sequence("Wild_V01");
  if (!std::filesystem::exists(dir / "trees.csv")) {
    FORESTMAP_SKIP_WITHOUT_DATA() << "real sequences missing under " << dir;
  }
  const auto frames = client::ReadFramesCsv((dir / "trees.csv").string());
  const auto poses = client::ReadPosesCsv((dir / "poses.csv").string());
  const auto reference = client::ToMapTrees(client::ReadMapTreesCsv((dir / "map.csv").string()));
  MergedMap map;
  std::vector<KdTree<double, 2>::Point> path;
  ASSERT_GE(frames.size(), 830u);
  for (size_t i = 430; i < 830; ++i) {
    FrameObservations frame;
    frame.source = "Wild_V01";
    frame.frame_id = frames[i].frame;
    frame.map_from_sensor = poses.at(frames[i].frame);
    frame.trees = frames[i].trees;
    map.Merge(frame);
    path.push_back(
        {frame.map_from_sensor.translation().x(), frame.map_from_sensor.translation().y()});
  }
  map.Consolidate();
  const KdTree<double, 2> path_xy(std::move(path));
  std::vector<MapTree> near_path;
  for (const MapTree& tree : reference) {
    if (path_xy.Nearest({tree.position.x(), tree.position.y()}).second < 100.0) {
      near_path.push_back(tree);
    }
  }
  ASSERT_GT(near_path.size(), 1000u);
  const std::vector<MapTree> confirmed = map.ConfirmedMapTrees();
  const TreeMapComparison c = CompareTreeMaps(confirmed, near_path);
  EXPECT_GE(c.found_fraction, 0.95);
  EXPECT_LE(c.distance_p50, 0.05);
  EXPECT_LE(c.dbh_abs_diff_p50, 0.01);
  EXPECT_LE(c.duplicates, static_cast<int>(confirmed.size() / 1000));  // <= 0.1%
}

TEST(MapMerge, InvalidOptionsAndInputsAreRejected) {
  MergeOptions options;
  options.promotion_views = 0;
  EXPECT_THROW(options.Check(), std::invalid_argument);
  FrameObservations frame = FrameAt({0, 0}, {Detection(1, 1, 0.2)});
  frame.map_from_sensor.translation().x() = std::nan("");
  EXPECT_THROW(MergeFrame({}, frame), std::invalid_argument);
  MergeResult result = MergeFrame({}, FrameAt({0, 0}, {Detection(1, 1, 0.2)}));
  const int64_t too_many[] = {5, 6};
  EXPECT_THROW(ResolveNewIds(result, too_many), std::invalid_argument);
  const TreeObservation orphan = SurveyObservation(MapTree{99, Eigen::Vector3d(1, 1, 0), 0.2});
  const TreeObservation rows[] = {orphan};
  EXPECT_THROW(ConsolidateTrees({}, rows), std::invalid_argument);
  EXPECT_THROW(RebuildTrees({}, rows, 1), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
