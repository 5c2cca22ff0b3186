// The relocalizer's decision against simulator truth: a pose must be more than the best chance
// coincidence of the whole search (significance.h), regular stands must not match a shifted
// copy of their grid, and the covariance must be calibrated (pose_covariance.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/decoys.h"
#include "algorithms/relocalization/pose_covariance.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/significance.h"
#include "algorithms/simulation/stand_cases.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/algorithms/relocalization/generated_forest.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

using testing_util::Forest;

PlantationOptions Grid(double spacing, double error, double mortality, unsigned seed) {
  PlantationOptions p;
  p.spacing_x = p.spacing_y = spacing;
  p.planting_error = error;
  p.mortality = mortality;
  p.width = p.height = 150;
  p.seed = seed;
  return p;
}

struct Outcomes {
  int localized = 0, correct = 0, views = 0;
  std::vector<double> nees;  // (x, y, yaw) of the correct answers
};

// `count` views of `views` (15 m, occlusion, 30% misses, 20% false stems, 5 cm noise), at least
// `margin` m inside it, relocalized in `index`.
Outcomes RunViewOutcomes(const std::vector<MapTree>& views, const MapIndex& index, int count,
                         unsigned seed, double margin = 15.0) {
  ViewSimulator simulator(views);
  Outcomes out;
  for (const Eigen::Vector3d& pose : simulator.SamplePoses(count, margin, seed, 8, 15.0)) {
    ViewOptions view;
    view.seed = seed * 1000 + static_cast<unsigned>(out.views++);
    const SimulatedView v = simulator.Simulate(pose.head<2>(), pose.z(), view);
    RelocalizeQuery query;
    query.trees = v.trees;
    const RelocalizeResult r = Relocalize(index, query);
    if (r.status != RelocalizeStatus::kLocalized) continue;
    ++out.localized;
    const PoseError e = ComparePoses(r.map_from_sensor, v.map_from_sensor);
    if (e.xy > 0.5 || e.yaw > 5) continue;
    ++out.correct;
    Eigen::Vector3d d;
    d << (r.map_from_sensor.translation() - v.map_from_sensor.translation()).head<2>(),
        WrapAngle(YawOf(r.map_from_sensor.linear()) - YawOf(v.map_from_sensor.linear()));
    Eigen::Matrix3d c;
    const int k[3] = {0, 1, 5};
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) c(a, b) = r.covariance(k[a], k[b]);
    }
    out.nees.push_back(d.dot(c.ldlt().solve(d)));
  }
  return out;
}

double Mean(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return v.empty() ? 0 : sum / v.size();
}

// A perfect grid matches a copy of itself shifted by any number of spacings: far from its
// edges, no view may be LOCALIZED (AMBIGUOUS with the shifted copy, or NOT_FOUND).
TEST(RelocalizerDecision, PerfectGridNeverMatchesItsShiftedCopy) {
  const std::vector<MapTree> grid = GeneratePlantation(Grid(4, 0.0, 0.0, 1));
  const MapIndex index(grid);
  const Outcomes o = RunViewOutcomes(grid, index, 40, 3, /*margin=*/25.0);
  EXPECT_EQ(o.views, 40);
  EXPECT_EQ(o.localized, 0);
}

// A plantation with planting errors: its own views are found (the true pose fits within the
// detection noise, a shifted grid within the planting error); views of another plantation of
// the same design are never LOCALIZED.
TEST(RelocalizerDecision, RegularStandTellsItsOwnGridFromAnotherOfTheSameDesign) {
  const std::vector<MapTree> own = GeneratePlantation(Grid(4, 0.2, 0.1, 1));
  const std::vector<MapTree> other = GeneratePlantation(Grid(4, 0.2, 0.1, 2));
  const MapIndex own_index(own), other_index(other);
  const Outcomes found = RunViewOutcomes(own, own_index, 50, 5);
  EXPECT_GE(found.correct, 48) << found.localized;
  EXPECT_EQ(found.correct, found.localized);
  EXPECT_EQ(RunViewOutcomes(own, other_index, 80, 6).localized, 0);
  EXPECT_EQ(RunViewOutcomes(other, own_index, 80, 7).localized, 0);
}

// Sparse natural stands, where a view holds 8-15 trees: the best of the search's chance poses
// explains about half of them; a true pose explains most.
TEST(RelocalizerDecision, SparseForeignStandsAreNeverLocalized) {
  const std::vector<MapTree> a = Forest(11, 200, 0.03), b = Forest(12, 200, 0.03);
  const MapIndex index_a(a), index_b(b);
  const Outcomes own = RunViewOutcomes(a, index_a, 60, 8);
  EXPECT_GE(own.correct, 57) << own.localized;
  EXPECT_EQ(own.correct, own.localized);
  EXPECT_EQ(RunViewOutcomes(a, index_b, 150, 9).localized, 0);
  EXPECT_EQ(RunViewOutcomes(b, index_a, 150, 10).localized, 0);
}

// The exact query of the map trees within 15 m of `truth` (kd coordinates), nearest first.
LevelledQuery ExactView(const std::vector<MapTree>& map, const MapIndexImpl& m,
                        const Rigid2& truth) {
  LevelledQuery q;
  for (const MapTree& t : map) {
    const Eigen::Vector2d local = t.position.head<2>() - m.origin - truth.translation;
    if (local.norm() <= 15.0) q.xy.push_back(Rigid2{-truth.yaw, {0, 0}}(local));
  }
  std::sort(q.xy.begin(), q.xy.end(),
            [](const auto& x, const auto& y) { return x.norm() < y.norm(); });
  q.z.assign(q.xy.size(), 0.0);
  q.dbh.assign(q.xy.size(), 0.0);
  return q;
}

// How many of `count` true poses in `map` Assess calls a regular stand.
int RegularAt(const std::vector<MapTree>& map, int count, unsigned seed) {
  const MapIndex index(map);
  const MapIndexImpl& m = index.impl();
  const RelocalizerOptions options;
  int regular = 0;
  for (const Eigen::Vector3d& pose : SamplePoses(map, count, 20.0, seed, 8, 15.0)) {
    Hypothesis truth;
    truth.pose = Rigid2{pose.z(), pose.head<2>() - m.origin};
    const LevelledQuery q = ExactView(map, m, truth.pose);
    Refine(m, q, options, &truth);
    regular += Assess(m, q, truth, {1000, SearchArea(m, std::nullopt)}, options).regular;
  }
  return regular;
}

// The chance level of a pose rises only where the stand is regular. A decoy turned half a circle
// about the midpoint of two matched trees swaps them in any stand: counted, it made sparse natural
// stands (8-15 trees a view) look five times as regular as random and their true poses
// insignificant. A plantation's shifted grid lands on trees again and again.
TEST(RelocalizerDecision, OnlyARegularStandRaisesTheChanceLevel) {
  EXPECT_EQ(RegularAt(Forest(31, 300, 0.015), 30, 32), 0);
  EXPECT_EQ(RegularAt(Forest(33, 200, 0.05), 30, 34), 0);
  EXPECT_EQ(RegularAt(GeneratePlantation(Grid(4, 0.2, 0.1, 1)), 30, 35), 30);
}

// The significance test against truth: the true pose of a view is significant; the same query
// mirrored (a constellation with the same ranges that no rigid motion puts on the map) is not,
// even at the pose that best fits it locally.
TEST(RelocalizerDecision, TruePoseIsSignificantAndTheMirroredQueryIsNot) {
  const std::vector<MapTree> map = Forest(13, 150, 0.05);
  const MapIndex index(map);
  const MapIndexImpl& m = index.impl();
  const RelocalizerOptions options;
  const SearchExtent global{1000, SearchArea(m, std::nullopt)};
  EXPECT_NEAR(global.area, 150.0 * 150.0, 0.35 * 150.0 * 150.0);
  const std::vector<Eigen::Vector3d> poses = SamplePoses(map, 10, 20.0, 14, 10, 15.0);
  ASSERT_EQ(poses.size(), 10u);
  for (const Eigen::Vector3d& pose : poses) {
    const Rigid2 truth{pose.z(), pose.head<2>() - m.origin};
    LevelledQuery q, mirrored;
    for (const MapTree& t : map) {
      const Eigen::Vector2d local = t.position.head<2>() - m.origin - truth.translation;
      if (local.norm() > 15.0) continue;
      const Eigen::Vector2d p = Rigid2{-truth.yaw, {0, 0}}(local);
      q.xy.push_back(p);
      mirrored.xy.push_back({p.x(), -p.y()});
    }
    for (LevelledQuery* l : {&q, &mirrored}) {
      std::sort(l->xy.begin(), l->xy.end(),
                [](const auto& x, const auto& y) { return x.norm() < y.norm(); });
      l->z.assign(l->xy.size(), 0.0);
      l->dbh.assign(l->xy.size(), 0.0);
    }
    const GateSignificance yes = TestSignificance(m, q, truth, global, 1.0, options);
    EXPECT_TRUE(yes.significant) << yes.inliers << " of " << q.xy.size();
    Hypothesis fit;
    fit.pose = truth;
    Refine(m, mirrored, options, &fit);
    const GateSignificance no = TestSignificance(m, mirrored, fit.pose, global, 1.0, options);
    EXPECT_FALSE(no.significant) << no.inliers << " of " << mirrored.xy.size();
  }
}

// Six trees explained exactly, in a large sparse map: significant when they are most of the
// nearby trees; not when as many again and more lie where the map has no tree (the likelihood
// ratio counts them against the pose).
LevelledQuery SixTreesAnd(int unexplained, const std::vector<MapTree>& map, const MapIndexImpl& m,
                          const Rigid2& truth) {
  LevelledQuery q;
  for (const MapTree& t : map) {
    const Eigen::Vector2d local = t.position.head<2>() - m.origin - truth.translation;
    if (local.norm() <= 15.0 && q.xy.size() < 6) q.xy.push_back(Rigid2{-truth.yaw, {0, 0}}(local));
  }
  for (int k = 0; k < unexplained; ++k) {  // trees the map does not have
    const double range = 5 + (k % 7), bearing = 2.4 * k;
    q.xy.push_back(range * Eigen::Vector2d(std::cos(bearing), std::sin(bearing)));
  }
  std::sort(q.xy.begin(), q.xy.end(),
            [](const auto& x, const auto& y) { return x.norm() < y.norm(); });
  q.z.assign(q.xy.size(), 0.0);
  q.dbh.assign(q.xy.size(), 0.0);
  return q;
}

TEST(RelocalizerDecision, UnexplainedNearbyTreesCountAgainstAPose) {
  const std::vector<MapTree> map = Forest(15, 400, 0.03);
  const MapIndex index(map);
  const MapIndexImpl& m = index.impl();
  const RelocalizerOptions options;
  const Rigid2 truth{0.4, Eigen::Vector2d(200, 200) - m.origin};
  const SearchExtent global{100, SearchArea(m, std::nullopt)}, prior{100, M_PI * 10 * 10};
  const LevelledQuery most = SixTreesAnd(2, map, m, truth), half = SixTreesAnd(14, map, m, truth);
  const GateSignificance most_global = TestSignificance(m, most, truth, global, 1.0, options);
  const GateSignificance half_global = TestSignificance(m, half, truth, global, 1.0, options);
  ASSERT_EQ(half_global.nearby_inliers, 6);
  EXPECT_TRUE(most_global.significant) << most_global.log_ratio;
  EXPECT_FALSE(half_global.significant) << half_global.log_ratio;
  EXPECT_LT(half_global.log_ratio, std::log(half_global.trials / options.false_alarm));
  // The look-elsewhere effect: the whole map holds 500 times the pose cells of a 10 m prior.
  PriorPose around;
  around.radius = 10;
  EXPECT_NEAR(SearchArea(m, around), M_PI * 100, 1e-9);
  EXPECT_NEAR(SearchArea(m, std::nullopt), 400.0 * 400.0, 0.3 * 400 * 400);
  EXPECT_GT(TestSignificance(m, half, truth, global, 1.0, options).trials,
            400 * TestSignificance(m, half, truth, prior, 1.0, options).trials);
}

// A map of the western half of a forest (the survey's edge a straight line), views simulated in
// the whole forest across the edge: judged on the trees inside what the map covers
// (coverage_share says how many), never a wrong pose.
TEST(RelocalizerDecision, ViewsAcrossTheSurveysEdgeAreJudgedOnWhatTheMapCovers) {
  const std::vector<MapTree> forest = Forest(21);
  std::vector<MapTree> west;
  for (const MapTree& tree : forest) {
    if (tree.position.x() < 100) west.push_back(tree);
  }
  const MapIndex index(west);
  ViewSimulator simulator(forest);
  int views = 0, localized = 0;
  for (int k = 0; k < 20; ++k, ++views) {
    ViewOptions view;
    view.seed = 500 + static_cast<unsigned>(k);
    const SimulatedView v = simulator.Simulate(Eigen::Vector2d(103, 30 + 7 * k), 0.3 * k, view);
    RelocalizeQuery query;
    query.trees = v.trees;
    const RelocalizeResult r = Relocalize(index, query);
    if (r.status != RelocalizeStatus::kLocalized) continue;
    ++localized;
    const PoseError e = ComparePoses(r.map_from_sensor, v.map_from_sensor);
    ASSERT_TRUE(e.xy < 0.5 && e.yaw < 5) << "wrong pose, view " << k;
    EXPECT_GT(r.coverage_share, 0.0);
    EXPECT_LT(r.coverage_share, 1.0) << "a view across the edge sees unmapped trees";
    EXPECT_GT(r.trees_in_coverage, 0);
  }
  EXPECT_GE(localized, views / 2);
}

// A survey that mapped the west half of a forest and, east of it, only one tree in ten (trees
// met on the way out): derived from its trees, the map covers the east too, and a view across
// the edge is judged against the east trees it sees and the map lacks. With the survey's
// boundary, those trees are neither support nor evidence: the views are found, never wrongly.
TEST(RelocalizerDecision, ASurveyBoundaryKeepsUnsurveyedTreesOutOfTheDecision) {
  const std::vector<MapTree> forest = Forest(23);
  std::vector<MapTree> surveyed;
  for (size_t i = 0; i < forest.size(); ++i) {
    if (forest[i].position.x() < 100 || i % 10 == 0) surveyed.push_back(forest[i]);
  }
  const Polygon west{{{0, 0}, {100, 0}, {100, 200}, {0, 200}}, {}};
  const MapIndex derived(surveyed), bounded(surveyed, {}, {west});
  EXPECT_FALSE(bounded.coverage_derived());
  EXPECT_TRUE(bounded.Covers({50, 100}));
  EXPECT_FALSE(bounded.Covers({150, 100}));
  ViewSimulator simulator(forest);
  int found_derived = 0, found_bounded = 0;
  for (int k = 0; k < 20; ++k) {
    ViewOptions view;
    view.seed = 700 + static_cast<unsigned>(k);
    const SimulatedView v = simulator.Simulate(Eigen::Vector2d(102, 30 + 7 * k), 0.3 * k, view);
    RelocalizeQuery query;
    query.trees = v.trees;
    for (const auto& [index, found] :
         {std::pair{&derived, &found_derived}, {&bounded, &found_bounded}}) {
      const RelocalizeResult r = Relocalize(*index, query);
      if (r.status != RelocalizeStatus::kLocalized) continue;
      const PoseError e = ComparePoses(r.map_from_sensor, v.map_from_sensor);
      ASSERT_TRUE(e.xy < 0.5 && e.yaw < 5) << "wrong pose, view " << k;
      ++*found;
    }
  }
  EXPECT_GE(found_bounded, 15);
  EXPECT_GE(found_bounded, found_derived + 5);
}

// A view whose best pose holds fewer than min_ratio_trees trees inside the map's coverage, the
// rest outside it, is NOT_FOUND for kOutsideCoverage; the same few trees seen alone (a small view
// wholly inside the map) fail for what they are (here too few inliers), not for the coverage.
TEST(RelocalizerDecision, AViewMostlyOutsideTheMapIsNotFoundForItsCoverage) {
  const std::vector<MapTree> forest = Forest(22);
  std::vector<MapTree> west, east;
  for (const MapTree& tree : forest) (tree.position.x() < 100 ? west : east).push_back(tree);
  const MapIndex index(west);
  const Eigen::Vector3d sensor(101, 100, 0);
  auto nearest = [&](std::vector<MapTree> trees, size_t count) {
    std::sort(trees.begin(), trees.end(), [&](const MapTree& a, const MapTree& b) {
      return (a.position - sensor).head<2>().norm() < (b.position - sensor).head<2>().norm();
    });
    trees.resize(count);
    std::vector<DetectedTree> detected;
    for (const MapTree& tree : trees) {
      DetectedTree d;
      d.position = tree.position - sensor;
      d.dbh = tree.dbh;
      detected.push_back(d);
    }
    return detected;
  };
  RelocalizerOptions options;
  options.min_inliers = 12;  // more than the 8 mapped trees in sight: never LOCALIZED here
  RelocalizeQuery alone;
  alone.trees = nearest(west, 8);
  RelocalizeQuery edge = alone;
  for (const DetectedTree& tree : nearest(east, 12)) edge.trees.push_back(tree);

  const RelocalizeResult at_edge = Relocalize(index, edge, options);
  EXPECT_EQ(at_edge.status, RelocalizeStatus::kNotFound);
  EXPECT_EQ(at_edge.reason, RelocalizeReason::kOutsideCoverage) << at_edge.detail;
  EXPECT_EQ(at_edge.trees_in_coverage, 8);
  EXPECT_LT(at_edge.coverage_share, 0.75);
  EXPECT_NE(at_edge.detail.find("inside what the map covers"), std::string::npos);

  const RelocalizeResult small = Relocalize(index, alone, options);
  EXPECT_EQ(small.status, RelocalizeStatus::kNotFound);
  EXPECT_NE(small.reason, RelocalizeReason::kOutsideCoverage) << small.detail;
  EXPECT_DOUBLE_EQ(small.coverage_share, 1.0);
}

// Covariance: the map's own error is what the residuals show beyond the detection noise; a
// perfect map (simulated views) gets none. Calibrated in the densest shared stem map
// (siplab_boreasNS, 0.47 trees/m^2, 150 matched trees a view), where the systematic term
// proportional to the whole residual made it three times too large (mean NEES 1.0).
TEST(RelocalizerDecision, CovarianceIsCalibratedInADenseStand) {
  PoseCovarianceInput tight, loose;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector2d p(10 * std::cos(i), 10 * std::sin(i));
    const Eigen::Vector2d r(std::cos(7.0 * i), std::sin(7.0 * i));
    tight.sensor_xy.push_back(p);
    tight.residual.push_back(0.04 * r);
    loose.sensor_xy.push_back(p);
    loose.residual.push_back(0.12 * r);
  }
  const double tight_var = PoseCovariance(tight)(0, 0), loose_var = PoseCovariance(loose)(0, 0);
  EXPECT_GT(loose_var, 1.2 * 9 * tight_var);  // 3x the residual: over 9x the variance

  const std::string path = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/siplab_boreasNS.csv";
  if (!std::filesystem::exists(path)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << path;
  const std::vector<MapTree> dense = client::ToMapTrees(client::ReadMapTreesCsv(path));
  const MapIndex index(dense);
  const Outcomes o = RunViewOutcomes(dense, index, 100, 17, /*margin=*/5.0);
  ASSERT_GE(o.nees.size(), 95u) << o.localized;
  EXPECT_GE(Mean(o.nees), 0.5 * 3) << "covariance too large";
  EXPECT_LE(Mean(o.nees), 2.0 * 3) << "covariance too small";
}

}  // namespace
}  // namespace forestmap::algorithms
