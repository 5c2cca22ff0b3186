// The relocalizer against simulator truth: simulated drone views of real stem maps, tilted
// sensors, 2-D maps, the prior path and honest refusals.
#include "algorithms/relocalization/relocalizer.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/simulation/view_simulator.h"
#include "client/io/tree_csv.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

// A real surveyed stem map of ../shared/data/stemmaps, or empty when the data is missing.
std::vector<MapTree> ReadStemMap(const std::string& name) {
  const std::string path = std::string(FORESTMAP_SHARED_DATA) + "/stemmaps/" + name;
  if (!std::filesystem::exists(path)) return {};
  return client::ToMapTrees(client::ReadMapTreesCsv(path));
}

// Relocalizes `count` simulated views of `map` (truth from the simulator).
RelocSummary RunViews(const std::vector<MapTree>& map, const MapIndex& index, int count,
                      ViewOptions view, bool with_prior, unsigned seed, double margin = 25.0) {
  ViewSimulator simulator(map);
  RelocEvaluator evaluator(map);
  const auto poses = simulator.SamplePoses(count, margin, seed, 8, view.range);
  for (size_t i = 0; i < poses.size(); ++i) {
    view.seed = seed * 1000 + static_cast<unsigned>(i);
    const SimulatedView v = simulator.Simulate(poses[i].head<2>(), poses[i].z(), view);
    RelocalizeQuery query;
    query.trees = v.trees;
    if (with_prior) {
      PriorPose prior;
      prior.map_from_sensor = v.map_from_sensor;
      prior.map_from_sensor.translation() += Eigen::Vector3d(2.0, -2.0, 0);  // 2.8 m off
      prior.radius = 10.0;
      query.prior = prior;
    }
    const RelocalizeResult r = Relocalize(index, query);
    evaluator.Add(evaluator.Answerable(v.trees, v.map_from_sensor), v.map_from_sensor, r, 0);
  }
  return evaluator.Summary();
}

class SimulatedViews : public ::testing::Test {
 protected:
  void SetUp() override {
    map_ = ReadStemMap("spatstat_longleaf.csv");
    if (map_.empty())
      FORESTMAP_SKIP_WITHOUT_DATA() << "real stem maps missing under " FORESTMAP_SHARED_DATA;
    index_ = std::make_unique<MapIndex>(map_);
  }
  std::vector<MapTree> map_;
  std::unique_ptr<MapIndex> index_;
};

TEST_F(SimulatedViews, LocalizesNoisyOccludedViewsOfARealStemMap) {
  ViewOptions view;   // 15 m range, occlusion, 30% misses, 20% false stems, 5 cm noise
  view.range = 25.0;  // longleaf is sparse (0.015 trees/m^2): a wider view sees enough trees
  const RelocSummary s = RunViews(map_, *index_, 150, view, false, 11);
  EXPECT_GT(s.answerable, 100);
  EXPECT_GE(s.recall, 0.95) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
  EXPECT_LT(s.error_xy_p50, 0.1);
}

TEST_F(SimulatedViews, LevelsSensorsTiltedUpTo45DegreesFromStemAxes) {
  ViewOptions view;
  view.range = 25.0;
  view.max_tilt = 0.785;
  const RelocSummary s = RunViews(map_, *index_, 100, view, false, 12);
  EXPECT_GE(s.recall, 0.95) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST_F(SimulatedViews, PriorPathFindsThePoseAndIgnoresTheRestOfTheMap) {
  ViewOptions view;
  view.range = 25.0;
  const RelocSummary s = RunViews(map_, *index_, 100, view, true, 13);
  EXPECT_GE(s.recall, 0.95);
  EXPECT_EQ(s.wrong, 0);

  // A prior far from the truth restricts the search to the wrong place: no answer, not a guess.
  ViewSimulator simulator(map_);
  const auto poses = simulator.SamplePoses(20, 25.0, 14, 8, 25.0);
  int localized = 0;
  for (const auto& p : poses) {
    const SimulatedView v = simulator.Simulate(p.head<2>(), p.z(), view);
    RelocalizeQuery query;
    query.trees = v.trees;
    PriorPose prior;
    prior.map_from_sensor = v.map_from_sensor;
    prior.map_from_sensor.translation() += Eigen::Vector3d(60.0, 0, 0);
    prior.radius = 10.0;
    query.prior = prior;
    localized += Relocalize(*index_, query).status == RelocalizeStatus::kLocalized;
  }
  EXPECT_EQ(localized, 0);
}

TEST(Relocalizer, TwoDimensionalMapWithoutDbhWorksInThreeDof) {
  std::vector<MapTree> map = ReadStemMap("spatstat_hyytiala.csv");  // x, y only
  if (map.empty())
    FORESTMAP_SKIP_WITHOUT_DATA() << "real stem maps missing under " FORESTMAP_SHARED_DATA;
  MapIndex index(map);
  EXPECT_FALSE(index.has_z());
  EXPECT_FALSE(index.has_dbh());
  ViewOptions view;
  view.range = 10.0;  // the plot is 20 x 20 m
  const RelocSummary s = RunViews(map, index, 60, view, false, 21, /*margin=*/2.0);
  EXPECT_GE(s.recall, 0.9) << s.correct << " of " << s.answerable;
  EXPECT_EQ(s.wrong, 0);
}

TEST(Relocalizer, ViewsOfAnotherForestAreNotFound) {
  std::vector<MapTree> map = ReadStemMap("spatstat_longleaf.csv");
  std::vector<MapTree> other = ReadStemMap("ads_BPoirier.csv");
  if (map.empty() || other.empty()) FORESTMAP_SKIP_WITHOUT_DATA() << "real stem maps missing";
  MapIndex index(map);
  ViewSimulator simulator(other);
  ViewOptions view;
  view.range = 25.0;
  int localized = 0;
  const auto poses = simulator.SamplePoses(100, 25.0, 31, 8, 25.0);
  for (size_t i = 0; i < poses.size(); ++i) {
    view.seed = static_cast<unsigned>(i);
    RelocalizeQuery query;
    query.trees = simulator.Simulate(poses[i].head<2>(), poses[i].z(), view).trees;
    localized += Relocalize(index, query).status == RelocalizeStatus::kLocalized;
  }
  EXPECT_EQ(localized, 0);
}

TEST(Relocalizer, TooFewTreesIsNotFoundNotAnError) {
  MapIndex index({{1, {0, 0, 0}, 0.3}, {2, {3, 0, 0}, 0.3}, {3, {0, 4, 0}, 0.3}});
  RelocalizeQuery query;
  query.trees.resize(2);
  const RelocalizeResult r = Relocalize(index, query);
  EXPECT_EQ(r.status, RelocalizeStatus::kNotFound);
  EXPECT_FALSE(r.detail.empty());
}

TEST(Relocalizer, InvalidOptionsThrow) {
  MapIndex index({});
  RelocalizerOptions options;
  options.inlier_distance = -1;
  EXPECT_THROW(Relocalize(index, {}, options), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::algorithms
