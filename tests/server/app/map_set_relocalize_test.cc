// One question over many maps, in the application layer: which maps may hold the sensor, and
// which map's answer the question gives, over plot maps cut from one generated forest in an
// in-memory store.
#include "server/app/map_set_relocalize.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "algorithms/simulation/view_simulator.h"
#include "storage/sqlite/store.h"
#include "tests/algorithms/relocalization/generated_forest.h"

namespace forestmap::server {
namespace {

using algorithms::RelocalizeStatus;

storage::MapInfo Info(const std::string& name, storage::Extent extent, int64_t confirmed = 10) {
  storage::MapInfo info;
  info.name = name;
  info.confirmed_count = confirmed;
  info.extent = extent;
  return info;
}

algorithms::RelocalizeQuery QueryWithin(double max_range, std::optional<Eigen::Vector2d> prior,
                                        double radius) {
  algorithms::RelocalizeQuery query;
  for (double r : {3.0, 7.0, max_range}) {
    algorithms::DetectedTree tree;
    tree.position = Eigen::Vector3d(0, r, 0);
    query.trees.push_back(tree);
  }
  if (prior) {
    query.prior = algorithms::PriorPose{};
    query.prior->map_from_sensor.translation().head<2>() = *prior;
    query.prior->radius = radius;
  }
  return query;
}

TEST(CandidateMaps, APriorKeepsTheMapsItsDiscGrownByTheViewMeets) {
  const std::vector<storage::MapInfo> maps = {
      Info("a", {0, 0, 100, 100}), Info("b", {100, 0, 200, 100}), Info("c", {300, 0, 400, 100}),
      Info("empty", {0, 0, 100, 100}, 0)};
  const algorithms::RelocalizerOptions options;  // max_query_range 60 m
  const auto names = [&](const algorithms::RelocalizeQuery& query) {
    std::vector<std::string> out;
    for (const storage::MapInfo& info : CandidateMaps(maps, query, options)) {
      out.push_back(info.name);
    }
    return out;
  };
  // No prior: every map with confirmed trees, in order.
  EXPECT_EQ(names(QueryWithin(20, {}, 0)), (std::vector<std::string>{"a", "b", "c"}));
  // At (50, 50) within 10 m, trees seen up to 20 m: b begins 50 m away, beyond 30 m.
  EXPECT_EQ(names(QueryWithin(20, Eigen::Vector2d(50, 50), 10)), (std::vector<std::string>{"a"}));
  // Seen up to 45 m: b's extent is within 55 m.
  EXPECT_EQ(names(QueryWithin(45, Eigen::Vector2d(50, 50), 10)),
            (std::vector<std::string>{"a", "b"}));
  // A tree 500 m away counts only up to max_query_range: c (250 m away) stays out.
  EXPECT_EQ(names(QueryWithin(500, Eigen::Vector2d(50, 50), 10)),
            (std::vector<std::string>{"a", "b"}));
  EXPECT_DOUBLE_EQ(ViewRange(QueryWithin(500, {}, 0), options), options.max_query_range);
}

// Maps of one CRS are one union, one index for every prior: the prior keeps all of them or none.
TEST(CandidateMaps, APriorKeepsEveryMapOfACrsItMeetsAndNoneOfOneItDoesNot) {
  std::vector<storage::MapInfo> maps = {Info("a", {0, 0, 100, 100}), Info("b", {100, 0, 200, 100}),
                                        Info("c", {300, 0, 400, 100}),
                                        Info("d", {1000, 0, 1100, 100})};
  maps[0].crs = maps[2].crs = "EPSG:32633";
  maps[1].crs = maps[3].crs = "EPSG:32632";
  std::vector<std::string> names;
  for (const storage::MapInfo& info :
       CandidateMaps(maps, QueryWithin(20, Eigen::Vector2d(50, 50), 10), {})) {
    names.push_back(info.name);
  }
  EXPECT_EQ(names, (std::vector<std::string>{"a", "c"}));
}

TEST(RelocalizeInMaps, NoMapToSearchIsNotFoundOutsideThePrior) {
  storage::SqliteMapStore store(":memory:");
  MapIndexCache cache(store);
  const MapSetAnswer answer = RelocalizeInMaps(cache, {}, QueryWithin(20, Eigen::Vector2d(0, 0), 5),
                                               algorithms::RelocalizerOptions());
  EXPECT_EQ(answer.result.status, RelocalizeStatus::kNotFound);
  EXPECT_EQ(answer.result.reason, algorithms::RelocalizeReason::kOutsidePrior);
  EXPECT_FALSE(answer.reported);
}

TEST(SearchCount, MapsOfOneCrsAreOneSearchAndAMapWithoutACrsIsItsOwn) {
  storage::MapInfo utm33a = MapNamed("a"), utm33b = MapNamed("b"), utm32 = MapNamed("c");
  utm33a.crs = utm33b.crs = "EPSG:32633";
  utm32.crs = "EPSG:32632";
  EXPECT_EQ(SearchCount({utm33a, utm33b}), 1u);
  EXPECT_EQ(SearchCount({utm33a, utm32, utm33b}), 2u);
  EXPECT_EQ(SearchCount({utm33a, MapNamed("x"), MapNamed("y")}), 3u);
}

storage::TreeRecord Record(const algorithms::MapTree& tree) {
  storage::TreeRecord record;
  record.id = tree.id;
  record.x = tree.position.x();
  record.y = tree.position.y();
  if (std::isfinite(tree.dbh)) record.dbh = tree.dbh;
  return record;
}

// Plots of one forest in one CRS, their ids their own (plot b's are the forest's + 10,000):
// a is x < 160, b is x >= 140; the 20 m strip between both surveyed it.
struct TwoPlots {
  std::vector<algorithms::MapTree> forest = algorithms::testing_util::Forest(7, 300);
  storage::SqliteMapStore store{":memory:"};
  std::vector<storage::MapInfo> maps;
  TwoPlots() {
    std::vector<storage::TreeRecord> a, b;
    for (const algorithms::MapTree& tree : forest) {
      if (tree.position.x() < 160) a.push_back(Record(tree));
      if (tree.position.x() >= 140) {
        b.push_back(Record(tree));
        b.back().id = tree.id + 10'000;
      }
    }
    for (const auto& [name, trees] : {std::pair{"a", &a}, std::pair{"b", &b}}) {
      store.CreateMap(name, "", "EPSG:32633");
      store.WriteTrees(name, *trees, storage::WriteMode::kAppend);
      maps.push_back(store.GetMap(name));
    }
  }
};

TEST(MapUnion, ATreeTwoMapsSurveyedIsIndexedOnceUnderItsFirstMapsId) {
  TwoPlots plots;
  const MapUnion maps = BuildMapUnion(plots.store, plots.maps, {});
  ASSERT_EQ(maps.members.size(), 2u);
  EXPECT_EQ(maps.index->size(), plots.forest.size());
  for (size_t i = 0; i < maps.origin.size(); ++i) {
    const MapUnion::Origin& origin = maps.origin[i];
    const bool in_a = maps.index->trees()[i].position.x() < 160;
    EXPECT_EQ(origin.member, in_a ? 0u : 1u) << i;
    EXPECT_EQ(origin.id >= 10'000, !in_a) << i;
  }
}

// A map of the set changes: questions go on with the union of the earlier versions, without
// waiting, until the background build of the new one is ready.
TEST(MapUnionCache, AChangedMapIsAnsweredFromTheLastUnionWhileTheNewOneBuilds) {
  TwoPlots plots;
  MapUnionCache cache(plots.store, {});
  const std::shared_ptr<const MapUnion> before = cache.Get(plots.maps);
  EXPECT_EQ(cache.Get(plots.maps), before);  // built once
  storage::TreeRecord added;
  added.x = 150;
  added.y = 310;  // outside the forest: no tree of either plot within reach
  plots.store.WriteTrees("b", {added}, storage::WriteMode::kAppend);
  std::vector<storage::MapInfo> changed = {plots.store.GetMap("a"), plots.store.GetMap("b")};
  ASSERT_GT(changed[1].version, plots.maps[1].version);
  const std::shared_ptr<const MapUnion> meanwhile = cache.Get(changed);
  EXPECT_EQ(meanwhile->members[1].version, plots.maps[1].version);  // the last one built
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (cache.background_builds() == 0 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(cache.background_builds(), 1);
  const std::shared_ptr<const MapUnion> after = cache.Get(changed);
  EXPECT_EQ(after->members[1].version, changed[1].version);
  EXPECT_EQ(after->index->size(), before->index->size() + 1);
  EXPECT_EQ(cache.Get(changed), after);  // and no further build
  EXPECT_EQ(cache.background_builds(), 1);
}

// A sensor on the line between the plots sees trees of both: one search, LOCALIZED at the
// truth, matches naming each tree's own map and id, and the map holding most of them answers.
TEST(RelocalizeInMaps, MapsOfOneCrsAreSearchedOnceAndAViewAcrossThemMatchesBoth) {
  TwoPlots plots;
  MapIndexCache cache(plots.store);
  const algorithms::ViewSimulator simulator(plots.forest);
  int across = 0;
  for (unsigned seed = 0; seed < 4; ++seed) {
    algorithms::ViewOptions view;
    view.seed = seed;
    view.range = 25;
    algorithms::RelocalizeQuery query;
    const Eigen::Vector2d truth(160, 60 + 40 * seed);
    query.trees = simulator.Simulate(truth, 0.5 * seed, view).trees;
    const MapSetAnswer answer =
        RelocalizeInMaps(cache, plots.maps, query, algorithms::RelocalizerOptions());
    ASSERT_EQ(answer.answers.size(), 1u);
    ASSERT_EQ(answer.result.status, RelocalizeStatus::kLocalized) << "seed " << seed;
    EXPECT_LT((answer.result.map_from_sensor.translation().head<2>() - truth).norm(), 0.3);
    const MapAnswer& reported = answer.answers[*answer.reported];
    ASSERT_EQ(reported.match_maps.size(), answer.result.matches.size());
    int in_a = 0, in_b = 0;
    for (size_t i = 0; i < reported.match_maps.size(); ++i) {
      const int64_t id = answer.result.matches[i].map_tree_id;
      const bool b = reported.match_maps[i] == "b";
      (b ? in_b : in_a) += 1;
      const algorithms::MapTree& tree = plots.forest.at(b ? id - 10'000 : id);
      EXPECT_EQ(tree.id, b ? id - 10'000 : id);
      EXPECT_EQ(tree.position.x() >= 160, b) << "tree " << id;
    }
    across += in_a > 0 && in_b > 0;
    EXPECT_EQ(reported.map, in_b > in_a ? "b" : "a");
    EXPECT_EQ(reported.entry.version, plots.store.GetMap(reported.map).version);
  }
  EXPECT_GE(across, 3);
}

// Plot a is the forest's x < 150, plot b its x >= 150 with every other tree (a thinner survey).
// A sensor just inside b sees more of a's trees than of b's: both maps localize it at one pose,
// and the question names b, the map whose coverage holds the sensor.
TEST(RelocalizeInMaps, MapsThatAgreeAreNamedByTheOneHoldingTheSensor) {
  const std::vector<algorithms::MapTree> forest = algorithms::testing_util::Forest(7, 300);
  storage::SqliteMapStore store(":memory:");
  std::vector<storage::TreeRecord> a, b;
  for (const algorithms::MapTree& tree : forest) {
    if (tree.position.x() < 150) {
      a.push_back(Record(tree));
    } else if (tree.id % 2 == 0) {
      b.push_back(Record(tree));
    }
  }
  store.CreateMap("a", "", "");
  store.WriteTrees("a", a, storage::WriteMode::kAppend);
  store.CreateMap("b", "", "");
  store.WriteTrees("b", b, storage::WriteMode::kAppend);
  MapIndexCache cache(store);
  const algorithms::ViewSimulator simulator(forest);
  int both = 0;
  for (unsigned seed = 0; seed < 6; ++seed) {
    algorithms::ViewOptions view;
    view.seed = seed;
    view.range = 25;
    algorithms::RelocalizeQuery query;
    query.trees = simulator.Simulate({156, 60 + 30 * seed}, 0.5 * seed, view).trees;
    const MapSetAnswer answer = RelocalizeInMaps(cache, {MapNamed("a"), MapNamed("b")}, query,
                                                 algorithms::RelocalizerOptions());
    ASSERT_EQ(answer.answers.size(), 2u);
    const algorithms::RelocalizeResult& in_a = answer.answers[0].result;
    const algorithms::RelocalizeResult& in_b = answer.answers[1].result;
    if (in_a.status != RelocalizeStatus::kLocalized ||
        in_b.status != RelocalizeStatus::kLocalized || in_a.inliers <= in_b.inliers) {
      continue;  // not the case this test is about
    }
    ++both;
    EXPECT_EQ(answer.result.status, RelocalizeStatus::kLocalized) << "seed " << seed;
    ASSERT_TRUE(answer.reported);
    EXPECT_EQ(answer.answers[*answer.reported].map, "b") << "seed " << seed;
    EXPECT_FALSE(answer.rival);
  }
  EXPECT_GE(both, 2);
}

}  // namespace
}  // namespace forestmap::server
