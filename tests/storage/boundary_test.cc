// A map's survey boundary on every backend: stored with the upload that gives it, versioned with
// the trees (every version reads its own), kept by an upload without one, restored, pruned and
// deleted with the map.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "storage/staged_writes.h"
#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

// A 100 m square with a 10 m square hole, and an irregular second polygon.
Boundary Square() {
  BoundaryPolygon polygon;
  polygon.outer = {{0, 0}, {100, 0}, {100, 100}, {0, 100}};
  polygon.holes = {{{40, 40}, {40, 50}, {50, 50}, {50, 40}}};
  BoundaryPolygon other;
  other.outer = {{200.125, 0.1}, {300.3333333333333, 0.2}, {250, 80.7}};
  return {polygon, other};
}

Boundary Triangle() {
  BoundaryPolygon polygon;
  polygon.outer = {{0, 0}, {50, 0}, {0, 50}};
  return {polygon};
}

MapInfo Upload(MapStore& store, const std::string& name, const std::vector<TreeRecord>& trees,
               std::optional<Boundary> boundary, WriteMode mode = WriteMode::kAppend,
               bool create = false) {
  UploadPlan plan;
  plan.mode = mode;
  plan.create_map = create;
  plan.boundary = std::move(boundary);
  auto upload = store.BeginUpload(name, plan);
  upload->Append(trees);
  return upload->Commit();
}

class BoundaryTest : public ::testing::TestWithParam<Backend> {
 protected:
  TestStore test_store_{GetParam()};
  MapStore& store_ = *test_store_;
};
INSTANTIATE_TEST_SUITE_P(Backends, BoundaryTest, kAllBackends, BackendName);

TEST_P(BoundaryTest, AnUploadStoresItExactlyWithTheTrees) {
  const MapInfo info = Upload(store_, "m", {Tree(1, 5, 5)}, Square(), WriteMode::kAppend, true);
  const MapSnapshot snapshot = store_.ReadMap("m");
  EXPECT_EQ(snapshot.info.version, info.version);
  EXPECT_EQ(snapshot.boundary, Square());  // every double back bit for bit, holes included
  EXPECT_EQ(store_.ReadMapVersion("m", info.version).boundary, Square());
}

TEST_P(BoundaryTest, AMapCreatedWithABoundaryAndNoTreesHasIt) {
  const MapInfo info = Upload(store_, "m", {}, Triangle(), WriteMode::kAppend, true);
  EXPECT_EQ(info.tree_count, 0);
  EXPECT_EQ(store_.ReadMap("m").boundary, Triangle());
  EXPECT_EQ(store_.ReadBoundary("m", 0), Triangle());
  EXPECT_TRUE(store_.ReadBoundary("m", 1).empty());  // the created version, before the upload's
}

TEST_P(BoundaryTest, AMapWithoutOneHasNone) {
  store_.CreateMap("m", "", "");
  store_.WriteTrees("m", {Tree(1, 5, 5)}, WriteMode::kAppend);
  EXPECT_TRUE(store_.ReadMap("m").boundary.empty());
}

TEST_P(BoundaryTest, VersionsKeepTheirOwnAndAnUploadWithoutOneKeepsIt) {
  store_.CreateMap("m", "", "");                                             // 1
  EXPECT_EQ(Upload(store_, "m", {Tree(1, 5, 5)}, Square()).version, 2);      // trees + boundary
  EXPECT_EQ(Upload(store_, "m", {Tree(2, 6, 6)}, std::nullopt).version, 3);  // keeps it
  EXPECT_EQ(store_.ReadMap("m").boundary, Square());
  // A changed boundary alone is a new version; the same one again is none.
  EXPECT_EQ(Upload(store_, "m", {}, Triangle()).version, 4);
  EXPECT_EQ(Upload(store_, "m", {}, Triangle()).version, 4);
  EXPECT_EQ(store_.ListVersions("m", 0).back().tree_count, 2);
  // An empty boundary removes it (a version of its own too).
  EXPECT_EQ(Upload(store_, "m", {}, Boundary{}).version, 5);
  EXPECT_TRUE(store_.ReadMap("m").boundary.empty());
  // A replace keeps it too when it gives none.
  Upload(store_, "m", {}, Square());                                        // 6
  Upload(store_, "m", {Tree(7, 1, 1)}, std::nullopt, WriteMode::kReplace);  // 7
  EXPECT_EQ(store_.ReadMap("m").boundary, Square());

  EXPECT_TRUE(store_.ReadMapVersion("m", 1).boundary.empty());
  EXPECT_EQ(store_.ReadMapVersion("m", 2).boundary, Square());
  EXPECT_EQ(store_.ReadMapVersion("m", 3).boundary, Square());
  EXPECT_EQ(store_.ReadMapVersion("m", 4).boundary, Triangle());
  EXPECT_TRUE(store_.ReadMapVersion("m", 5).boundary.empty());
  EXPECT_EQ(store_.ReadMapVersion("m", 7).boundary, Square());
  // Other writes leave it.
  store_.WriteTrees("m", {Tree(8, 2, 2)}, WriteMode::kAppend);  // 8
  EXPECT_EQ(store_.ReadMap("m").boundary, Square());
}

TEST_P(BoundaryTest, RestorePruneAndDeleteFollowTheVersions) {
  store_.CreateMap("m", "", "");                       // 1
  Upload(store_, "m", {Tree(1, 5, 5)}, Triangle());    // 2
  Upload(store_, "m", {Tree(2, 6, 6)}, Square());      // 3
  Upload(store_, "m", {Tree(3, 7, 7)}, std::nullopt);  // 4
  EXPECT_EQ(store_.RestoreVersion("m", 2).version, 5);
  EXPECT_EQ(store_.ReadMap("m").boundary, Triangle());
  EXPECT_EQ(store_.ReadMapVersion("m", 4).boundary, Square());
  EXPECT_EQ(store_.RestoreVersion("m", 1).version, 6);
  EXPECT_TRUE(store_.ReadMap("m").boundary.empty());

  // Keeping versions 4..6: version 4 still reads the boundary set at version 3.
  store_.PruneVersions("m", 3);
  EXPECT_EQ(store_.ReadMapVersion("m", 4).boundary, Square());
  EXPECT_EQ(store_.ReadMapVersion("m", 5).boundary, Triangle());
  EXPECT_TRUE(store_.ReadMapVersion("m", 6).boundary.empty());
  if (GetParam() != Backend::kSqlite) {
    // Only the rows of kept versions stay: the one in force at version 4, and those after it.
    EXPECT_EQ(test_store_.Column("SELECT version FROM map_boundaries ORDER BY version"),
              (std::vector<std::string>{"3", "5", "6"}));
  }
  store_.DeleteMap("m");
  store_.CreateMap("m", "", "");
  EXPECT_TRUE(store_.ReadMap("m").boundary.empty());
}

TEST_P(BoundaryTest, AnInvalidBoundaryIsRefusedBeforeAnythingIsWritten) {
  store_.CreateMap("m", "", "");
  Boundary two = Triangle();
  two[0].outer.pop_back();
  ExpectError([&] { Upload(store_, "m", {Tree(1, 1, 1)}, two); }, Code::kInvalidArgument,
              "boundary polygon 0 outer ring has 2 vertices");
  Boundary nan = Square();
  nan[0].holes[0][1].y = std::numeric_limits<double>::quiet_NaN();
  ExpectError([&] { Upload(store_, "m", {Tree(1, 1, 1)}, nan); }, Code::kInvalidArgument,
              "boundary polygon 0 hole 0 has a vertex that is not finite");
  BoundaryPolygon huge;
  for (size_t i = 0; i <= kMaxBoundaryVertices; ++i) {
    const double angle = 2 * M_PI * static_cast<double>(i) / (kMaxBoundaryVertices + 1);
    huge.outer.push_back({std::cos(angle), std::sin(angle)});
  }
  ExpectError([&] { Upload(store_, "m", {Tree(1, 1, 1)}, Boundary{huge}); }, Code::kInvalidArgument,
              "at most 100000");
  EXPECT_EQ(store_.GetMap("m").version, 1);
  EXPECT_EQ(store_.GetMap("m").tree_count, 0);
}

}  // namespace
}  // namespace forestmap::storage
