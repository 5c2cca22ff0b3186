// Evidence of absence (algorithms/merging/absence.h, absence_evidence.h) against synthetic
// geometry whose answer is known, and MergedMap::Observe removing felled trees and retiring
// false stems in a simulated forest.

#include "algorithms/merging/absence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "algorithms/merging/absence_evidence.h"
#include "algorithms/merging/merged_map.h"
#include "algorithms/simulation/view_simulator.h"

namespace forestmap::algorithms {
namespace {

MapTree Tree(int64_t id, double x, double y, double dbh = 0.3) {
  return {id, Eigen::Vector3d(x, y, 0), dbh};
}

DetectedTree DetectionAt(double x, double y, double dbh = 0.3) {
  DetectedTree tree;
  tree.position = Eigen::Vector3d(x, y, 0);
  tree.dbh = dbh;
  tree.axis = Eigen::Vector3d::UnitZ();
  return tree;
}

AbsenceOptions Stated(double range = 15, double p = 0.9) {
  AbsenceOptions options;
  options.range = range;
  options.detection_probability = p;
  return options;
}

// The sensor at the origin, identity pose: sensor frame = map frame.
AbsenceObservation At(std::vector<DetectedTree> trees) {
  AbsenceObservation observation;
  observation.trees = std::move(trees);
  return observation;
}

TEST(ExpectTrees, InRangeUnhiddenAndUndetectedIsMissed) {
  const std::vector<MapTree> map = {Tree(1, 5, 0), Tree(2, 0, 8), Tree(3, -6, -6)};
  const AbsenceResult result = ExpectTrees(map, At({DetectionAt(0.2, 8.1)}), Stated());
  ASSERT_EQ(result.trees.size(), 3u);
  EXPECT_EQ(result.trees[0].visibility, Visibility::kMissed);
  EXPECT_EQ(result.trees[1].visibility, Visibility::kSeen);
  EXPECT_EQ(result.trees[2].visibility, Visibility::kMissed);
  EXPECT_EQ(result.expected, 3);
  EXPECT_EQ(result.seen, 1);
  // p falls linearly from p0 at the sensor to far_ratio * p0 at the range.
  EXPECT_NEAR(result.trees[0].detection_probability, 0.9 * (1 - 0.5 * 5.0 / 15.0), 1e-12);
}

TEST(ExpectTrees, TreeBehindANearerTrunkIsNotExpected) {
  // Tree 2 stands 10 m out on the bearing of tree 1 at 4 m; tree 3 is 2 m beside tree 2.
  const std::vector<MapTree> map = {Tree(1, 4, 0), Tree(2, 10, 0), Tree(3, 10, 2)};
  const AbsenceResult result = ExpectTrees(map, At({DetectionAt(4, 0)}), Stated());
  EXPECT_EQ(result.trees[0].visibility, Visibility::kSeen);
  EXPECT_EQ(result.trees[1].visibility, Visibility::kNotExpected);
  EXPECT_EQ(result.trees[2].visibility, Visibility::kMissed);
}

TEST(ExpectTrees, AStemTheMapDoesNotHaveAlsoHides) {
  // A detection at 3 m (ingrowth, not in the map) shadows the map tree at 9 m behind it.
  const std::vector<MapTree> map = {Tree(1, 9, 0.1)};
  EXPECT_EQ(ExpectTrees(map, At({}), Stated()).trees[0].visibility, Visibility::kMissed);
  EXPECT_EQ(ExpectTrees(map, At({DetectionAt(3, 0)}), Stated()).trees[0].visibility,
            Visibility::kNotExpected);
}

TEST(ExpectTrees, ACandidateHidesNothingAndTeachesNothing) {
  // A candidate at 4 m on the bearing of a confirmed tree at 10 m: it may be a false stem, so the
  // tree behind it is still expected; the candidate itself, in view and undetected, is missed.
  const std::vector<MapTree> established = {Tree(1, 10, 0)};
  const std::vector<MapTree> candidates = {Tree(2, 4, 0)};
  const AbsenceResult result = ExpectTrees(established, {}, candidates, At({}), Stated());
  ASSERT_EQ(result.trees.size(), 2u);
  EXPECT_EQ(result.trees[0].id, 1);
  EXPECT_EQ(result.trees[0].visibility, Visibility::kMissed);
  EXPECT_EQ(result.trees[1].visibility, Visibility::kMissed);
  // Detected candidates do not teach the range: five of them are not enough to learn one.
  std::vector<MapTree> five;
  std::vector<DetectedTree> detections;
  for (int k = 0; k < 5; ++k) {
    five.push_back(Tree(10 + k, 3.0 + k, 2.0 * k));
    detections.push_back(DetectionAt(3.0 + k, 2.0 * k));
  }
  EXPECT_EQ(ExpectTrees({}, {}, five, At(detections)).range_source, SensorModelSource::kNone);
  EXPECT_EQ(ExpectTrees(five, {}, {}, At(detections)).range_source, SensorModelSource::kLearned);
}

TEST(ExpectTrees, TheDetectionRateIsLearnedFromTreesKnownToStand) {
  // Twelve confirmed trees at 5 m on distinct bearings, half of them felled (not detected).
  // Learned from all, p0 looks like half the truth; learned from the six seen standing since the
  // survey, as the detector really is (capped).
  std::vector<MapTree> map;
  std::vector<DetectedTree> detections;
  std::vector<char> standing;
  for (int k = 0; k < 12; ++k) {
    const double bearing = 2 * M_PI * k / 12;
    map.push_back(Tree(k + 1, 5 * std::cos(bearing), 5 * std::sin(bearing)));
    standing.push_back(k % 2 == 0);
    if (k % 2 == 0) detections.push_back(DetectionAt(5 * std::cos(bearing), 5 * std::sin(bearing)));
  }
  AbsenceOptions options;
  options.range = 15;
  const AbsenceResult all = ExpectTrees(map, {}, {}, At(detections), options);
  const AbsenceResult known = ExpectTrees(map, standing, {}, At(detections), options);
  const double shape = 1 - 0.5 * 5.0 / 15.0;
  EXPECT_FALSE(all.learned_from_standing);
  EXPECT_NEAR(all.detection_probability, 0.5 / shape, 1e-12);
  EXPECT_TRUE(known.learned_from_standing);
  EXPECT_DOUBLE_EQ(known.detection_probability, options.max_detection_probability);
}

TEST(ExpectTrees, ADetectionSeesOnlyTheNearestTreeInItsGate) {
  // Two trees 0.4 m apart across the line of sight; one detection on the first: the second,
  // standing beside it and not behind it, is missed (one stem, one tree).
  const std::vector<MapTree> map = {Tree(1, 8, 0, 0.2), Tree(2, 8, 0.4, 0.1)};
  const AbsenceResult result = ExpectTrees(map, At({DetectionAt(8.02, 0, 0.2)}), Stated());
  EXPECT_EQ(result.trees[0].visibility, Visibility::kSeen);
  EXPECT_EQ(result.trees[1].visibility, Visibility::kMissed);
  // The same pair along the line of sight: the detection in front hides the tree behind it.
  const std::vector<MapTree> in_line = {Tree(1, 8, 0, 0.2), Tree(2, 8.4, 0, 0.1)};
  EXPECT_EQ(ExpectTrees(in_line, At({DetectionAt(8.02, 0, 0.2)}), Stated()).trees[1].visibility,
            Visibility::kNotExpected);
}

TEST(ExpectTrees, OutOfRangeAndRangeEdgeAreNotExpected) {
  const std::vector<MapTree> map = {Tree(1, 20, 0), Tree(2, 0, 14.5), Tree(3, 0, -13)};
  const AbsenceResult result = ExpectTrees(map, At({}), Stated(15));
  EXPECT_EQ(result.trees[0].visibility, Visibility::kNotExpected);  // beyond the range
  EXPECT_EQ(result.trees[1].visibility, Visibility::kNotExpected);  // within edge_margin of it
  EXPECT_EQ(result.trees[2].visibility, Visibility::kMissed);
}

TEST(ExpectTrees, RangeAndRateAreLearnedFromTheDetectionsOfMapTrees) {
  // Ten map trees detected at 2..11 m on distinct bearings; one undetected tree at 6 m and one at
  // 14 m. The learned range (0.9 quantile of 2..11) is 10 m: the far one is not expected.
  std::vector<MapTree> map;
  std::vector<DetectedTree> detections;
  for (int k = 0; k < 10; ++k) {
    const double bearing = 0.5 * k, r = 2.0 + k;
    map.push_back(Tree(k + 1, r * std::cos(bearing), r * std::sin(bearing)));
    detections.push_back(DetectionAt(r * std::cos(bearing), r * std::sin(bearing)));
  }
  map.push_back(Tree(11, 6 * std::cos(5.25), 6 * std::sin(5.25)));
  map.push_back(Tree(12, 14 * std::cos(5.75), 14 * std::sin(5.75)));
  const AbsenceResult result = ExpectTrees(map, At(detections));
  EXPECT_EQ(result.range_source, SensorModelSource::kLearned);
  EXPECT_DOUBLE_EQ(result.range, 10.0);
  EXPECT_EQ(result.trees[10].visibility, Visibility::kMissed);
  EXPECT_EQ(result.trees[11].visibility, Visibility::kNotExpected);
  // p0 learned so that the expected detections of the unhidden trees in range equal those seen,
  // capped below certainty.
  EXPECT_EQ(result.probability_source, SensorModelSource::kLearned);
  EXPECT_GT(result.detection_probability, 0.5);
  EXPECT_LE(result.detection_probability, AbsenceOptions{}.max_detection_probability);
}

TEST(ExpectTrees, NothingToLearnFromGivesNoEvidence) {
  // A frame over a clear-cut: no detections, nothing stated: nothing is expected ...
  const std::vector<MapTree> map = {Tree(1, 5, 0), Tree(2, 0, 5)};
  const AbsenceResult unknown = ExpectTrees(map, At({}));
  EXPECT_EQ(unknown.range_source, SensorModelSource::kNone);
  EXPECT_EQ(unknown.expected, 0);
  // ... with the sensor's range and rate stated (or learned by the source before), both missed.
  EXPECT_EQ(ExpectTrees(map, At({}), Stated()).missed, 2);
}

TEST(ExpectTrees, PoseUncertaintyWidensTheGate) {
  const std::vector<MapTree> map = {Tree(1, 10, 0)};
  AbsenceObservation observation = At({DetectionAt(10, 0.9)});
  EXPECT_EQ(ExpectTrees(map, observation, Stated()).trees[0].visibility, Visibility::kMissed);
  observation.pose_sigma_yaw = 0.05;  // rad: 0.5 m at 10 m, 1.5 m with 3 sigmas
  EXPECT_EQ(ExpectTrees(map, observation, Stated()).trees[0].visibility, Visibility::kSeen);
}

TEST(AbsenceEvidence, FourIndependentMissesAtPointNineRemoveThreeDoNot) {
  const AbsenceEvidenceOptions options;
  const double per_miss = -std::log(1 - 0.9 * (1 - options.shared_miss));
  TreeEvidence evidence;
  for (int k = 1; k <= 4; ++k) {
    AddMiss(evidence, "drone-" + std::to_string(k), 0.9);
    EXPECT_NEAR(GoneLogLikelihoodRatio(evidence, options), k * per_miss, 1e-12);
    EXPECT_EQ(IsGone(evidence, options), k == 4) << k << " misses";
  }
}

TEST(AbsenceEvidence, ACandidateRetiresAfterTwoMissesAtPointNine) {
  TreeEvidence evidence;
  AddSighting(evidence, "drone/1", 1);
  AddMiss(evidence, "drone/2", 0.9);
  EXPECT_FALSE(IsGone(evidence, {}, /*candidate=*/true));
  AddMiss(evidence, "drone/3", 0.9);
  EXPECT_TRUE(IsGone(evidence, {}, /*candidate=*/true));
  EXPECT_FALSE(IsGone(evidence, {}, /*candidate=*/false));
}

TEST(AbsenceEvidence, OneSourceAloneNeverRemoves) {
  const AbsenceEvidenceOptions options;
  TreeEvidence evidence;
  for (int k = 0; k < 1000; ++k) AddMiss(evidence, "drone", 0.94);
  EXPECT_NEAR(GoneLogLikelihoodRatio(evidence, options), std::log(1 / options.shared_miss), 1e-9);
  EXPECT_FALSE(IsGone(evidence, options));
  for (int k = 0; k < 1000; ++k) AddMiss(evidence, "drone-2", 0.94);
  EXPECT_FALSE(IsGone(evidence, options));  // two sources: alpha < eps^2 keeps it
  AddMiss(evidence, "drone-3", 0.9);
  AddMiss(evidence, "drone-3", 0.9);
  EXPECT_TRUE(IsGone(evidence, options));
}

TEST(AbsenceEvidence, ATreeSeenOnceAfterMissesStays) {
  TreeEvidence evidence;
  for (int k = 0; k < 3; ++k) AddMiss(evidence, "drone-" + std::to_string(k), 0.9);
  AddSighting(evidence, "drone-9", 42);
  EXPECT_EQ(GoneLogLikelihoodRatio(evidence), 0.0);
  EXPECT_EQ(evidence.last_seen, 42);
  EXPECT_EQ(evidence.last_seen_group, "drone-9");
  for (int k = 0; k < 3; ++k) AddMiss(evidence, "drone-" + std::to_string(k), 0.9);
  EXPECT_FALSE(IsGone(evidence));  // the misses before the sighting no longer count
}

TEST(AbsenceEvidence, OptionsAreChecked) {
  AbsenceEvidenceOptions options;
  options.false_removal = 0.01;  // >= eps^2: two sources could remove a tree
  EXPECT_THROW(options.Check(), std::invalid_argument);
  TreeEvidence evidence;
  EXPECT_THROW(AddMiss(evidence, "d", 1.0), std::invalid_argument);
  AbsenceOptions absence;
  absence.range_quantile = 0;
  EXPECT_THROW(absence.Check(), std::invalid_argument);
}

// A drone flies along y = 20 through a surveyed 10 m grid and detects every tree within 15 m;
// its last frame also reports a stem at (30, 22.5) where none stands.
std::vector<TimedFrame> LineFlight(const std::vector<MapTree>& survey, const std::string& last) {
  std::vector<TimedFrame> frames;
  for (int k = 0; k <= 20; ++k) {
    TimedFrame frame;
    const Eigen::Vector3d sensor(2.0 * k, 20, 0);
    frame.frame.source = k < 20 ? "a" : last;
    frame.frame.frame_id = k;
    frame.frame.map_from_sensor = Pose3::Identity();
    frame.frame.map_from_sensor.translation() = sensor;
    for (const MapTree& tree : survey) {
      if ((tree.position - sensor).head<2>().norm() <= 15) {
        frame.frame.trees.push_back(
            DetectionAt(tree.position.x() - sensor.x(), tree.position.y() - sensor.y(), tree.dbh));
      }
    }
    if (k == 20) frame.frame.trees.push_back(DetectionAt(30 - sensor.x(), 2.5, 0.3));
    frame.time = k;
    frames.push_back(frame);
  }
  return frames;
}

TEST(MergedMapObserve, AFalseStemIsWeighedAgainstItsSourcesEarlierViews) {
  std::vector<MapTree> survey;
  for (int x = 0; x <= 40; x += 10) {
    for (int y = 0; y <= 40; y += 10)
      survey.push_back(Tree(static_cast<int64_t>(survey.size()) + 1, x, y));
  }
  for (const std::string last : {"a", "b"}) {
    MergedMap map;
    map.AddSurvey(survey);
    ObserveResult result;
    for (const TimedFrame& frame : LineFlight(survey, last)) result = map.Observe(frame);
    ASSERT_EQ(result.merge.new_trees.size(), 1u);
    const int64_t stem = result.merge.new_trees[0].id;
    // Source a looked at (30, 22.5) from x = 16..38 and saw nothing there: the same pass's views
    // count both ways in time. Source b's stem may be a tree that grew since a flew: a's earlier
    // views do not count against it.
    EXPECT_EQ(map.removed().count(stem), last == "a" ? 1u : 0u) << last;
    EXPECT_TRUE(map.removed().size() == (last == "a" ? 1u : 0u)) << "no surveyed tree removed";
  }
}

// A surveyed 60 m x 60 m grid forest, 5 m spacing; a fifth of its trees felled; six drone
// passes fly the felled forest along lines 10 m apart, one source per pass, the last without
// false stems. Truth decides the score. A felled tree can stay when a false stem lands on it late
// or fewer than three passes missed it since; a live tree must never go.
TEST(MergedMapObserve, FelledTreesAreRemovedLiveTreesStayFalseStemsRetire) {
  std::vector<MapTree> survey, standing;
  std::set<int64_t> felled;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-1.0, 1.0);
  int64_t id = 1;
  for (double x = 0; x <= 60; x += 5) {
    for (double y = 0; y <= 60; y += 5) {
      const MapTree tree = Tree(id++, x + jitter(rng), y + jitter(rng), 0.25);
      survey.push_back(tree);
      if (rng() % 5 == 0) {
        felled.insert(tree.id);
      } else {
        standing.push_back(tree);
      }
    }
  }
  MergedMap map;
  map.AddSurvey(survey);
  const ViewSimulator simulator(standing);
  ViewOptions view;
  view.range = 15;
  view.miss_rate = 0.1;
  view.far_miss_rate = 0.3;
  int frame_id = 0, false_candidates = 0;
  for (int pass = 0; pass < 6; ++pass) {
    view.false_rate = pass < 5 ? 0.1 : 0.0;
    for (double y = 5; y <= 55; y += 10) {
      for (double x = 0; x <= 60; x += 3) {
        view.seed = static_cast<unsigned>(++frame_id);
        const SimulatedView sim = simulator.Simulate({x, y + pass}, 0.1 * frame_id, view);
        TimedFrame frame;
        frame.frame = {"pass-" + std::to_string(pass), frame_id, sim.map_from_sensor, sim.trees};
        frame.time = frame_id;
        false_candidates += static_cast<int>(map.Observe(frame).merge.new_trees.size());
      }
    }
  }
  int felled_removed = 0, live_removed = 0;
  for (const auto& [removed_id, removed] : map.removed()) {
    if (removed_id > static_cast<int64_t>(survey.size())) continue;  // a retired candidate
    (felled.count(removed_id) ? felled_removed : live_removed)++;
  }
  EXPECT_EQ(live_removed, 0);
  EXPECT_GE(felled_removed, 0.9 * static_cast<double>(felled.size()));
  // False stems inside the flown area, where later views look, retire.
  int candidates_left = 0;
  for (const TreeEstimate& tree : map.Trees()) {
    const Eigen::Vector2d xy = tree.position.head<2>();
    candidates_left +=
        tree.status == TreeStatus::kCandidate && xy.minCoeff() >= 0 && xy.maxCoeff() <= 60;
  }
  EXPECT_GT(false_candidates, 100);
  EXPECT_LT(candidates_left, false_candidates / 10);
  // A removed tree is restorable, with its rows.
  ASSERT_GT(felled_removed, 0);
  const int64_t restored = map.removed().begin()->first;  // the smallest id: a surveyed tree
  EXPECT_TRUE(map.Restore(restored));
  EXPECT_EQ(map.TreesNear(survey[restored - 1].position.head<2>(), 0.01).size(), 1u);
  EXPECT_FALSE(map.Restore(restored));
}

}  // namespace
}  // namespace forestmap::algorithms
