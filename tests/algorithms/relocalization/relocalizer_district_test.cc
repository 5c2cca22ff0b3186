// The relocalizer across a forest district: reasons in every answer, look-alike plantations
// (regular grids), views outside the map, and the pose covariance, against simulator truth.
#include <gtest/gtest.h>

#include <cmath>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/simulation/stand_cases.h"
#include "algorithms/simulation/view_simulator.h"
#include "tests/algorithms/relocalization/generated_forest.h"

namespace forestmap::algorithms {
namespace {

using testing_util::Forest;

SimulatedView SimulatedViewAt(const std::vector<MapTree>& map, double x, double y, double yaw,
                              unsigned seed) {
  ViewOptions view;
  view.seed = seed;
  return ViewSimulator(map).Simulate({x, y}, yaw, view);
}

TEST(RelocalizerReasons, TooFewTreesIsNotFoundWithItsReason) {
  const std::vector<MapTree> map = Forest(1);
  const MapIndex index(map);
  const SimulatedView view = SimulatedViewAt(map, 100, 100, 0, 1);
  for (size_t n : {0, 1, 2}) {
    RelocalizeQuery query;
    query.trees.assign(view.trees.begin(), view.trees.begin() + n);
    const RelocalizeResult r = Relocalize(index, query);
    EXPECT_EQ(r.status, RelocalizeStatus::kNotFound);
    EXPECT_EQ(r.reason, RelocalizeReason::kTooFewTrees);
    EXPECT_NE(r.detail.find("the query has " + std::to_string(n)), std::string::npos) << r.detail;
  }
}

TEST(RelocalizerReasons, LocalizedAnswerHasNoReasonAndAForeignOneSaysWhy) {
  const std::vector<MapTree> map = Forest(1), other = Forest(2);
  const MapIndex index(map);
  RelocalizeQuery query;
  const SimulatedView v = SimulatedViewAt(map, 100, 100, 0.3, 2);
  query.trees = v.trees;
  const RelocalizeResult found = Relocalize(index, query);
  ASSERT_EQ(found.status, RelocalizeStatus::kLocalized) << found.detail;
  EXPECT_EQ(found.reason, RelocalizeReason::kNone);
  EXPECT_LT(ComparePoses(found.map_from_sensor, v.map_from_sensor).xy, 0.2);

  int not_found = 0;
  for (unsigned k = 0; k < 20; ++k) {
    query.trees = SimulatedViewAt(other, 30 + 7 * k, 40 + 6 * k, 0.1 * k, 10 + k).trees;
    const RelocalizeResult r = Relocalize(index, query);
    ASSERT_NE(r.status, RelocalizeStatus::kLocalized) << "view " << k << ": " << r.detail;
    if (r.status != RelocalizeStatus::kNotFound) continue;
    ++not_found;
    EXPECT_TRUE(r.reason == RelocalizeReason::kNoMatchingConstellation ||
                r.reason == RelocalizeReason::kNotSignificant ||
                r.reason == RelocalizeReason::kTooFewInliers ||
                r.reason == RelocalizeReason::kOutsideCoverage)
        << ToString(r.reason);
  }
  EXPECT_GE(not_found, 18);
}

TEST(RelocalizerReasons, RepeatedPatchIsAmbiguousWithTheRivalsPose) {
  // The map's 60 m x 60 m corner copied 120 m away: a view inside it fits both copies.
  std::vector<MapTree> map = Forest(3, 240);
  const size_t n = map.size();
  for (size_t i = 0; i < n; ++i) {
    if (map[i].position.x() >= 60 || map[i].position.y() >= 60) continue;
    MapTree copy = map[i];
    copy.id = static_cast<int64_t>(map.size());
    copy.position.x() += 120;
    copy.position.y() += 120;
    map.push_back(copy);
  }
  std::erase_if(map, [&](const MapTree& t) {  // the originals where the copy went
    return t.id < static_cast<int64_t>(n) && t.position.x() >= 120 && t.position.x() < 180 &&
           t.position.y() >= 120 && t.position.y() < 180;
  });
  const MapIndex index(map);
  RelocalizeQuery query;
  const SimulatedView v = SimulatedViewAt(map, 30, 30, 1.0, 4);
  query.trees = v.trees;
  const RelocalizeResult r = Relocalize(index, query);
  ASSERT_EQ(r.status, RelocalizeStatus::kAmbiguous) << r.detail;
  EXPECT_EQ(r.reason, RelocalizeReason::kAmbiguous);
  ASSERT_TRUE(r.rival_map_from_sensor.has_value());
  const Eigen::Vector2d rival = r.rival_map_from_sensor->translation().head<2>();
  const double to_truth = (rival - Eigen::Vector2d(30, 30)).norm();
  const double to_copy = (rival - Eigen::Vector2d(150, 150)).norm();
  EXPECT_LT(std::min(to_truth, to_copy), 0.5) << rival.transpose();
}

TEST(RelocalizerReasons, PoseOutsideThePriorSaysSo) {
  const std::vector<MapTree> map = Forest(1);
  const MapIndex index(map);
  const SimulatedView v = SimulatedViewAt(map, 100, 100, -0.5, 5);
  RelocalizeQuery query;
  query.trees = v.trees;
  PriorPose prior;
  prior.map_from_sensor = v.map_from_sensor;
  prior.map_from_sensor.translation() += Eigen::Vector3d(40, 0, 0);
  prior.radius = 10;
  query.prior = prior;
  const RelocalizeResult r = Relocalize(index, query);
  EXPECT_EQ(r.status, RelocalizeStatus::kNotFound);
  EXPECT_EQ(r.reason, RelocalizeReason::kOutsidePrior) << r.detail;
  EXPECT_NE(r.detail.find("40.0 m from it"), std::string::npos) << r.detail;
}

// Views of `views` relocalized in `index` (built from `views` or from another stand).
RelocSummary RunDistrictViews(const std::vector<MapTree>& views, const MapIndex& index, int count,
                              unsigned seed, std::vector<double>* nees = nullptr) {
  ViewSimulator simulator(views);
  RelocEvaluator evaluator(views);
  const auto poses = simulator.SamplePoses(count, 15.0, seed, 8, 15.0);
  for (size_t i = 0; i < poses.size(); ++i) {
    ViewOptions view;  // 15 m, occlusion, 30% misses, 20% false stems, 5 cm noise
    view.seed = seed * 1000 + static_cast<unsigned>(i);
    const SimulatedView v = simulator.Simulate(poses[i].head<2>(), poses[i].z(), view);
    RelocalizeQuery query;
    query.trees = v.trees;
    const RelocalizeResult r = Relocalize(index, query);
    evaluator.Add(evaluator.Answerable(v.trees, v.map_from_sensor), v.map_from_sensor, r, 0);
    const PoseError e = ComparePoses(r.map_from_sensor, v.map_from_sensor);
    if (nees && r.status == RelocalizeStatus::kLocalized && e.xy < 0.5 && e.yaw < 5) {
      Eigen::Vector3d d;
      d << (r.map_from_sensor.translation() - v.map_from_sensor.translation()).head<2>(),
          WrapAngle(YawOf(r.map_from_sensor.linear()) - YawOf(v.map_from_sensor.linear()));
      Eigen::Matrix3d c;
      const int k[3] = {0, 1, 5};
      for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) c(a, b) = r.covariance(k[a], k[b]);
      }
      nees->push_back(d.dot(c.ldlt().solve(d)));
    }
  }
  return evaluator.Summary();
}

PlantationOptions Design(double sx, double sy, double error, double mortality, unsigned seed) {
  PlantationOptions p;
  p.spacing_x = sx;
  p.spacing_y = sy;
  p.planting_error = error;
  p.mortality = mortality;
  p.width = p.height = 150;
  p.seed = seed;
  return p;
}

TEST(StandCases, PlantationIsAGridWithItsMortalityAndMosaicTilesEveryStand) {
  const std::vector<MapTree> p = GeneratePlantation(Design(4, 5, 0.2, 0.1, 1));
  EXPECT_NEAR(p.size(), 0.9 * 37 * 30, 40);
  for (const MapTree& t : p) {
    EXPECT_LT(std::abs(std::remainder(t.position.x() - 2, 4.0)), 1.2);  // 6 sd
    EXPECT_LT(std::abs(std::remainder(t.position.y() - 2.5, 5.0)), 1.2);
  }
  EXPECT_THROW(GeneratePlantation(Design(4, 4, 0.2, 1.0, 1)), std::invalid_argument);
  MosaicOptions mosaic;
  mosaic.trees = 20000;
  const std::vector<MapTree> d = TileMosaic({Forest(1), p}, mosaic);
  EXPECT_GE(d.size(), 20000u);
  EXPECT_LT(d.size(), 20000u + 2000u);
  EXPECT_THROW(TileMosaic({Forest(1, 400)}, mosaic), std::invalid_argument);  // wider than a tile
}

TEST(RelocalizerPlantation, OwnMapIsFoundAndAnotherPlantationIsNeverLocalized) {
  for (const PlantationOptions& design :
       {Design(5, 5, 0.2, 0.05, 1), Design(4, 4, 0.5, 0.25, 1), Design(3, 2.5, 0.3, 0.15, 1)}) {
    const std::vector<MapTree> own = GeneratePlantation(design);
    PlantationOptions other = design;
    other.seed = 2;
    const MapIndex own_index(own), other_index(GeneratePlantation(other));
    const RelocSummary found = RunDistrictViews(own, own_index, 60, 21);
    EXPECT_GE(found.recall, 0.95) << design.spacing_x << " m: " << found.correct << " of "
                                  << found.answerable;
    EXPECT_EQ(found.wrong, 0) << design.spacing_x << " m";
    const RelocSummary foreign = RunDistrictViews(own, other_index, 60, 22);
    EXPECT_EQ(foreign.localized, 0) << design.spacing_x << " m";
  }
}

// A district of stands thirty times apart in density, indexed under the tight per-tree budget
// of a large map: each stand gets triangles of its own scale, and views of both are found.
TEST(RelocalizerMosaic, DenseAndSparseStandsAreEachIndexedAtTheirOwnScale) {
  MosaicOptions mosaic;
  mosaic.trees = 12000;
  mosaic.seed = 5;
  const std::vector<MapTree> district =
      TileMosaic({Forest(1, 60, 0.45), Forest(2, 200, 0.015)}, mosaic);
  MapIndexOptions options;
  options.large_map_trees = 1000;  // the budget of a million-tree map
  const MapIndex index(district, options);
  size_t short_sides = 0, long_sides = 0;
  for (const auto& [side, count] : index.triangle_levels()) {
    if (side <= 3.5) short_sides += count;
    if (side >= 9.0) long_sides += count;
  }
  EXPECT_GT(short_sides, 5 * district.size() / 10);  // the dense stands
  EXPECT_GT(long_sides, district.size() / 10);       // the sparse ones: 10-30 m
  EXPECT_LT(index.triangle_count(), 13 * district.size());
  const RelocSummary s = RunDistrictViews(district, index, 120, 31);
  EXPECT_GE(s.recall, 0.95) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST(RelocalizerCovariance, NormalisedErrorMatchesItsDegreesOfFreedom) {
  const std::vector<MapTree> map = Forest(7);
  const MapIndex index(map);
  std::vector<double> nees;
  const RelocSummary s = RunDistrictViews(map, index, 150, 23, &nees);
  ASSERT_GT(nees.size(), 100u) << s.localized;
  double mean = 0;
  for (double v : nees) mean += v / nees.size();
  EXPECT_GE(mean, 0.5 * 3) << "covariance too large";
  EXPECT_LE(mean, 2.0 * 3) << "covariance too small";
}

}  // namespace
}  // namespace forestmap::algorithms
