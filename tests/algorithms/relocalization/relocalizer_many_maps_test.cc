// One question over many maps: the area a query searches in a map (what the other maps of the
// question add to its look-elsewhere test), and the test growing stricter with that area.
#include <gtest/gtest.h>

#include <cmath>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/simulation/view_simulator.h"
#include "tests/algorithms/relocalization/generated_forest.h"

namespace forestmap::algorithms {
namespace {

using testing_util::Forest;

RelocalizeQuery QueryAt(const std::vector<MapTree>& map, double x, double y, double yaw,
                        unsigned seed, Pose3* truth = nullptr) {
  ViewOptions view;
  view.seed = seed;
  const SimulatedView v = ViewSimulator(map).Simulate({x, y}, yaw, view);
  if (truth != nullptr) *truth = v.map_from_sensor;
  RelocalizeQuery query;
  query.trees = v.trees;
  return query;
}

TEST(QuerySearchArea, IsTheCoverageGrownByTheViewOrThePriorsDiscWhenSmaller) {
  const std::vector<MapTree> map = Forest(1);  // 200 m x 200 m
  const MapIndex index(map);
  RelocalizeQuery query = QueryAt(map, 100, 100, 0.2, 1);
  const double global = QuerySearchArea(index, query);
  // At least the coverage, at most the forest grown by the largest reach (60 m) on every side.
  EXPECT_GE(global, index.coverage_area());
  EXPECT_LE(global, 320.0 * 320.0);
  query.prior = PriorPose{};
  query.prior->map_from_sensor.translation() = Eigen::Vector3d(100, 100, 0);
  query.prior->radius = 25;
  EXPECT_DOUBLE_EQ(QuerySearchArea(index, query), M_PI * 25 * 25);
  query.prior->radius = 1e4;  // a disc beyond the map: the map's own area counts
  EXPECT_DOUBLE_EQ(QuerySearchArea(index, query), global);
}

TEST(OtherSearchArea, AddsToTheLookElsewhereTestAndNeverMakesAnAnswerWrong) {
  const std::vector<MapTree> map = Forest(4);
  const MapIndex index(map);
  Pose3 truth;
  RelocalizeQuery query = QueryAt(map, 90, 110, 0.7, 3, &truth);
  const RelocalizeResult alone = Relocalize(index, query);
  ASSERT_EQ(alone.status, RelocalizeStatus::kLocalized) << alone.detail;
  // A district of 100 such maps: still found, at the same pose.
  query.other_search_area = 99 * QuerySearchArea(index, query);
  const RelocalizeResult district = Relocalize(index, query);
  ASSERT_EQ(district.status, RelocalizeStatus::kLocalized) << district.detail;
  EXPECT_LT(ComparePoses(district.map_from_sensor, truth).xy, 0.2);
  // An area so large that no inlier count can beat chance in it: not significant.
  query.other_search_area = 1e300;
  const RelocalizeResult absurd = Relocalize(index, query);
  EXPECT_EQ(absurd.status, RelocalizeStatus::kNotFound) << absurd.detail;
  EXPECT_EQ(absurd.reason, RelocalizeReason::kNotSignificant) << ToString(absurd.reason);
}

TEST(OtherSearchArea, ForeignViewsStayUnlocalizedOverADistrict) {
  const std::vector<MapTree> map = Forest(1), other = Forest(2);
  const MapIndex index(map);
  for (unsigned k = 0; k < 10; ++k) {
    RelocalizeQuery query = QueryAt(other, 30 + 13 * k, 40 + 11 * k, 0.3 * k, 20 + k);
    query.other_search_area = 49 * QuerySearchArea(index, query);
    const RelocalizeResult r = Relocalize(index, query);
    EXPECT_NE(r.status, RelocalizeStatus::kLocalized) << "view " << k << ": " << r.detail;
  }
}

}  // namespace
}  // namespace forestmap::algorithms
